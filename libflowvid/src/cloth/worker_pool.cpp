#include "flowvid/cloth/worker_pool.hpp"

#include <chrono>
#include <cstdint>

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

namespace {

// The job's claim state: generation in the high half, next task in the low.
constexpr std::uint64_t pack(std::uint32_t generation, std::uint32_t next) {
    return (static_cast<std::uint64_t>(generation) << 32) | next;
}

}  // namespace

bool WorkerPool::claim(std::uint32_t generation, int count, int& task) {
    std::uint64_t state = m_claim.load(std::memory_order_acquire);
    for (;;) {
        if (static_cast<std::uint32_t>(state >> 32) != generation) return false;  // a later job: not ours
        const std::uint32_t next = static_cast<std::uint32_t>(state);
        if (static_cast<int>(next) >= count) return false;
        if (m_claim.compare_exchange_weak(state, pack(generation, next + 1), std::memory_order_acq_rel))
            break;
    }
    task = static_cast<int>(static_cast<std::uint32_t>(state));
    return true;
}

void WorkerPool::run(int count, const std::function<void(int)>& task) {
    if (m_threads == 1 || count <= 1) {
        for (int k = 0; k < count; ++k) task(k);
        return;
    }
    std::uint32_t generation;
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_task = &task;
        m_count = count;
        m_done.store(0, std::memory_order_relaxed);
        generation = m_generation.load(std::memory_order_relaxed) + 1;
        m_claim.store(pack(generation, 0), std::memory_order_release);
        m_generation.store(generation, std::memory_order_release);
    }
    m_wake.notify_all();
    // Tasks are claimed, not assigned: on a busy machine a worker that has not
    // been scheduled yet leaves its share to this thread instead of stalling
    // it. Which thread runs a task never changes the result.
    for (int k; claim(generation, count, k);) {
        task(k);
        m_done.fetch_add(1, std::memory_order_acq_rel);
    }
    // Only tasks already running on a worker remain (tens of microseconds).
    while (m_done.load(std::memory_order_acquire) != count) std::this_thread::yield();
}

void WorkerPool::worker(int) {
    std::uint32_t seen = 0;
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
        const std::function<void(int)>* task;
        int count;
        {
            // Task, count and generation read together: a job that has
            // already finished is recognised by claim() and left alone. The
            // stop is checked here too: the generation read may be the
            // destructor's, which no later wake-up would follow.
            std::lock_guard<std::mutex> lock(m_mutex);
            if (m_stop) return;
            task = m_task;
            count = m_count;
            seen = m_generation.load(std::memory_order_acquire);
        }
        for (int k; claim(seen, count, k);) {
            (*task)(k);
            m_done.fetch_add(1, std::memory_order_acq_rel);
        }
    }
}

}  // namespace flowvid::cloth::detail
