#pragma once
// A tiny fork-join pool for the cloth hot loops (std::thread only; OpenMP is
// not configured). run(count, task) calls task(k) for k in [0, count) on the
// calling thread and the workers, each claiming the next unclaimed task.
// Which thread runs a task never changes a result: callers give each task its
// own output and combine outputs in task order.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace flowvid::cloth::detail {

class WorkerPool {
public:
    explicit WorkerPool(int threads);
    ~WorkerPool();
    WorkerPool(const WorkerPool&) = delete;
    WorkerPool& operator=(const WorkerPool&) = delete;

    int threads() const { return m_threads; }
    void run(int count, const std::function<void(int)>& task);

private:
    void worker(int index);
    // Claims the next task of job `generation`; false when none is left.
    bool claim(std::uint32_t generation, int count, int& task);

    int m_threads = 1;
    std::vector<std::thread> m_workers;
    std::mutex m_mutex;
    std::condition_variable m_wake;
    std::atomic<std::uint32_t> m_generation{0};
    std::atomic<std::uint64_t> m_claim{0};  // generation << 32 | next task
    std::atomic<int> m_done{0};             // tasks of the current job finished
    std::atomic<bool> m_stop{false};
    const std::function<void(int)>* m_task = nullptr;
    int m_count = 0;
};

}  // namespace flowvid::cloth::detail
