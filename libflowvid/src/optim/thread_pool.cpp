#include "flowvid/optim/thread_pool.hpp"

#include <algorithm>

namespace flowvid::optim {

ThreadPool::ThreadPool(int threads) : m_threads(resolve_thread_count(threads)) {
    for (int w = 1; w < m_threads; ++w) m_workers.emplace_back([this, w] { work(w); });
}

ThreadPool::~ThreadPool() {
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_stop = true;
    }
    m_wake.notify_all();
    for (std::thread& t : m_workers) t.join();
}

// Takes indices until the batch is exhausted. Called with the lock held;
// releases it while a task runs.
void ThreadPool::drain(int worker) {
    std::unique_lock<std::mutex> lock(m_mutex, std::adopt_lock);
    while (m_task && m_next < m_count && !m_error) {
        const std::size_t index = m_next++;
        ++m_active;
        const auto* task = m_task;
        lock.unlock();
        std::exception_ptr error;
        try {
            (*task)(index, worker);
        } catch (...) {
            error = std::current_exception();
        }
        lock.lock();
        --m_active;
        if (error && !m_error) m_error = error;
    }
    if (m_active == 0) m_done.notify_all();
    lock.release();
}

void ThreadPool::work(int worker) {
    unsigned long long seen = 0;
    std::unique_lock<std::mutex> lock(m_mutex);
    for (;;) {
        m_wake.wait(lock, [&] { return m_stop || m_generation != seen; });
        if (m_stop) return;
        seen = m_generation;
        lock.release();  // drain() adopts the held mutex and returns holding it
        drain(worker);
        lock = std::unique_lock<std::mutex>(m_mutex, std::adopt_lock);
    }
}

void ThreadPool::run(std::size_t count, const std::function<void(std::size_t, int)>& task) {
    if (count == 0) return;
    if (m_threads == 1 || count == 1) {
        for (std::size_t i = 0; i < count; ++i) task(i, 0);
        return;
    }
    std::unique_lock<std::mutex> lock(m_mutex);
    m_task = &task;
    m_count = count;
    m_next = 0;
    m_error = nullptr;
    ++m_generation;
    m_wake.notify_all();
    lock.release();
    drain(0);
    lock = std::unique_lock<std::mutex>(m_mutex, std::adopt_lock);
    m_done.wait(lock, [&] { return m_active == 0 && (m_next >= m_count || m_error); });
    m_task = nullptr;
    std::exception_ptr error = m_error;
    m_error = nullptr;
    lock.unlock();
    if (error) std::rethrow_exception(error);
}

}  // namespace flowvid::optim
