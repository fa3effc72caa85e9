#include "flowvid/threads.hpp"

#include <algorithm>
#include <thread>

namespace flowvid {

int resolve_thread_count(int requested) {
    if (requested > 0) return requested;
    return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

}  // namespace flowvid
