#include "flowvid/thread_pool.hpp"

#include "flowvid/threads.hpp"

#include <chrono>
#include <limits>
#include <stdexcept>

namespace flowvid {

namespace {

// The job's claim state: generation in the high half, next index in the low.
constexpr std::uint64_t pack(std::uint32_t generation, std::uint32_t next) {
    return (static_cast<std::uint64_t>(generation) << 32) | next;
}

}  // namespace

ThreadPool::ThreadPool(int threads) : m_threads(resolve_thread_count(threads)) {
    for (int w = 1; w < m_threads; ++w) m_workers.emplace_back([this, w] { worker(w); });
}

ThreadPool::~ThreadPool() {
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_stop = true;
        m_generation.fetch_add(1, std::memory_order_release);
    }
    m_wake.notify_all();
    for (std::thread& t : m_workers) t.join();
}

bool ThreadPool::claim(std::uint32_t generation, std::size_t count, std::size_t& index) {
    std::uint64_t state = m_claim.load(std::memory_order_acquire);
    for (;;) {
        if (static_cast<std::uint32_t>(state >> 32) != generation) return false;  // a later job: not ours
        const std::uint32_t next = static_cast<std::uint32_t>(state);
        if (next >= count) return false;
        if (m_claim.compare_exchange_weak(state, pack(generation, next + 1), std::memory_order_acq_rel)) break;
    }
    index = static_cast<std::uint32_t>(state);
    return true;
}

void ThreadPool::execute(const std::function<void(std::size_t, int)>& task, std::size_t index, int worker) {
    if (!m_failed.load(std::memory_order_acquire)) {
        try {
            task(index, worker);
        } catch (...) {
            const std::lock_guard<std::mutex> lock(m_mutex);
            if (!m_error) m_error = std::current_exception();
            m_failed.store(true, std::memory_order_release);
        }
    }
    m_done.fetch_add(1, std::memory_order_acq_rel);
}

void ThreadPool::run(std::size_t count, const std::function<void(std::size_t, int)>& task) {
    if (count == 0) return;
    if (m_threads == 1 || count == 1) {
        for (std::size_t i = 0; i < count; ++i) task(i, 0);
        return;
    }
    if (count > std::numeric_limits<std::uint32_t>::max() - 1)
        throw std::length_error("ThreadPool::run: more than 2^32 - 1 indices in one job");
    std::uint32_t generation;
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        m_task = &task;
        m_count = count;
        m_done.store(0, std::memory_order_relaxed);
        m_failed.store(false, std::memory_order_relaxed);
        m_error = nullptr;
        generation = m_generation.load(std::memory_order_relaxed) + 1;
        m_claim.store(pack(generation, 0), std::memory_order_release);
        m_generation.store(generation, std::memory_order_release);
    }
    m_wake.notify_all();
    for (std::size_t i; claim(generation, count, i);) execute(task, i, 0);
    // Only indices already running on a worker remain.
    while (m_done.load(std::memory_order_acquire) != count) std::this_thread::yield();
    std::exception_ptr error;
    {
        const std::lock_guard<std::mutex> lock(m_mutex);
        error = m_error;
        m_error = nullptr;
    }
    if (error) std::rethrow_exception(error);
}

void ThreadPool::worker(int index) {
    std::uint32_t seen = 0;
    for (;;) {
        // Spin briefly for the next job (the cloth solver's come every few
        // tens of microseconds), then sleep.
        const auto spin_until = std::chrono::steady_clock::now() + std::chrono::microseconds(200);
        while (m_generation.load(std::memory_order_acquire) == seen && std::chrono::steady_clock::now() < spin_until)
            std::this_thread::yield();
        if (m_generation.load(std::memory_order_acquire) == seen) {
            std::unique_lock<std::mutex> lock(m_mutex);
            m_wake.wait(lock, [&] { return m_generation.load(std::memory_order_acquire) != seen; });
        }
        const std::function<void(std::size_t, int)>* task;
        std::size_t count;
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
        for (std::size_t i; claim(seen, count, i);) execute(*task, i, index);
    }
}

}  // namespace flowvid
