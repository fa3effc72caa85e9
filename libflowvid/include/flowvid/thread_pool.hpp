#pragma once
// The library's one pool of worker threads, for its parallel loops: the
// cloth model's element and solver loops (jobs every few tens of
// microseconds) and batches of simulations in the fits (seconds each).
//
// run(count, task) calls task(index, worker) for every index in [0, count)
// and returns when all have run; `worker` in [0, threads()) says which thread
// runs it (the caller is worker 0), so a task can use per-worker scratch.
// Indices are claimed, not assigned: on a busy machine a worker that is not
// scheduled leaves its share to the others instead of stalling the job.
// Which thread runs an index therefore varies; callers write each index's
// result to its own slot and combine in index order, which keeps results
// independent of the thread count. Workers spin briefly between jobs, then
// sleep.

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace flowvid {

class ThreadPool {
public:
    // `threads` as every threads setting means it (flowvid/threads.hpp: 0 = every core).
    explicit ThreadPool(int threads = 0);
    ~ThreadPool();
    ThreadPool(const ThreadPool&) = delete;
    ThreadPool& operator=(const ThreadPool&) = delete;

    int threads() const { return m_threads; }

    // Runs the job. The first exception a task throws is rethrown here once
    // the job is over; indices not yet started are then skipped. Not
    // re-entrant: do not call run() from inside a task. At most 2^32 - 1 indices.
    void run(std::size_t count, const std::function<void(std::size_t index, int worker)>& task);

private:
    void worker(int index);
    // Claims the next index of job `generation`; false when none is left.
    bool claim(std::uint32_t generation, std::size_t count, std::size_t& index);
    // Runs one claimed index (unless an earlier one failed) and counts it done.
    void execute(const std::function<void(std::size_t, int)>& task, std::size_t index, int worker);

    int m_threads = 1;
    std::vector<std::thread> m_workers;
    std::mutex m_mutex;
    std::condition_variable m_wake;
    std::atomic<std::uint32_t> m_generation{0};
    std::atomic<std::uint64_t> m_claim{0};  // generation << 32 | next index
    std::atomic<std::size_t> m_done{0};     // indices of the current job finished
    std::atomic<bool> m_stop{false};
    std::atomic<bool> m_failed{false};
    std::exception_ptr m_error;  // the job's first exception (under m_mutex)
    const std::function<void(std::size_t, int)>* m_task = nullptr;
    std::size_t m_count = 0;
};

}  // namespace flowvid
