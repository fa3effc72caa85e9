#pragma once
// How many threads a `threads` setting means, one rule for every setting of
// the library and the command line: a positive count is taken as it is, 0 (or
// less) means every core (std::thread::hardware_concurrency(), at least 1).

namespace flowvid {

int resolve_thread_count(int requested);

}  // namespace flowvid
