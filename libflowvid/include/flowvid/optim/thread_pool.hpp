#pragma once
// A fixed pool of std::threads for batches of independent evaluations
// (simulations of parameter sets). run(count, task) calls task(index, worker)
// for every index in [0, count) and returns when all are done; `worker` in
// [0, threads()) says which thread runs it (the caller is worker 0), so a task
// can use per-worker scratch (renderers, angle mappers). Indices are handed
// out dynamically, so which worker runs which index varies; callers write each
// index's result to its own slot and combine in index order, which makes
// results independent of the thread count.

#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include "flowvid/threads.hpp"

#include <mutex>
#include <thread>
#include <vector>

namespace flowvid::optim {

class ThreadPool {
public:
    // threads <= 0: std::thread::hardware_concurrency() (at least 1).
    explicit ThreadPool(int threads = 0);
    ~ThreadPool();
    ThreadPool(const ThreadPool&) = delete;
    ThreadPool& operator=(const ThreadPool&) = delete;

    int threads() const { return m_threads; }

    // Runs the batch; the first exception thrown by a task is rethrown here
    // after every started task has finished (remaining indices are skipped).
    // Not re-entrant: do not call run() from inside a task.
    void run(std::size_t count, const std::function<void(std::size_t index, int worker)>& task);

private:
    void work(int worker);
    void drain(int worker);

    int m_threads = 1;
    std::vector<std::thread> m_workers;
    std::mutex m_mutex;
    std::condition_variable m_wake;
    std::condition_variable m_done;
    const std::function<void(std::size_t, int)>* m_task = nullptr;
    std::size_t m_count = 0;
    std::size_t m_next = 0;
    int m_active = 0;
    unsigned long long m_generation = 0;
    bool m_stop = false;
    std::exception_ptr m_error;
};

// Number of threads `requested` means (<= 0: all cores; flowvid/threads.hpp).
using flowvid::resolve_thread_count;

}  // namespace flowvid::optim
