#include "flowvid/cloth/worker_pool.hpp"

#include <chrono>

namespace flowvid::cloth::detail {

WorkerPool::WorkerPool(int threads) : m_threads(threads < 1 ? 1 : threads) {
    for (int w = 1; w < m_threads; ++w) m_workers.emplace_back([this, w] { worker(w); });
}

WorkerPool::~WorkerPool() {
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_stop = true;
        m_generation.fetch_add(1, std::memory_order_release);
    }
    m_wake.notify_all();
    for (std::thread& t : m_workers) t.join();
}

void WorkerPool::run(int count, const std::function<void(int)>& task) {
    if (m_threads == 1 || count <= 1) {
        for (int k = 0; k < count; ++k) task(k);
        return;
    }
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_task = &task;
        m_count = count;
        m_pending.store(m_threads - 1, std::memory_order_relaxed);
        m_generation.fetch_add(1, std::memory_order_release);
    }
    m_wake.notify_all();
    for (int k = 0; k < count; k += m_threads) task(k);
    // The workers' share is short (tens of microseconds): wait by spinning,
    // yielding so that an oversubscribed machine is not starved.
    while (m_pending.load(std::memory_order_acquire) != 0) std::this_thread::yield();
}

void WorkerPool::worker(int index) {
    unsigned seen = 0;
    for (;;) {
        // Spin briefly for the next job (CG iterations come every few tens of
        // microseconds), then sleep.
        const auto spin_until = std::chrono::steady_clock::now() + std::chrono::microseconds(200);
        while (m_generation.load(std::memory_order_acquire) == seen && std::chrono::steady_clock::now() < spin_until)
            std::this_thread::yield();
        if (m_generation.load(std::memory_order_acquire) == seen) {
            std::unique_lock<std::mutex> lock(m_mutex);
            m_wake.wait(lock, [&] { return m_generation.load(std::memory_order_acquire) != seen; });
        }
        seen = m_generation.load(std::memory_order_acquire);
        if (m_stop) return;
        const std::function<void(int)>* task;
        int count;
        {
            std::lock_guard<std::mutex> lock(m_mutex);
            task = m_task;
            count = m_count;
        }
        for (int k = index; k < count; k += m_threads) (*task)(k);
        m_pending.fetch_sub(1, std::memory_order_acq_rel);
    }
}

}  // namespace flowvid::cloth::detail
