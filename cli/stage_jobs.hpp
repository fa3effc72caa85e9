#pragma once
// Programs run side by side, each after the ones it waits for, at most N at
// once: how `flowvid demo` keeps two cores busy when one stage alone uses
// about one and a half. Each program's stdout and stderr go to files; the
// caller hears when one starts and ends, and gets a tick while any runs.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace flowvid::cli {

struct StageJob {
    std::string name;
    std::vector<std::string> argv;  // argv[0] is looked up on PATH
    // Names of jobs that must end before this one starts. An order only: a
    // job that failed still lets its followers run.
    std::vector<std::string> after;
    std::filesystem::path stdout_file;
    std::filesystem::path stderr_file;
};

struct StageJobEnd {
    int exit_code = 0;  // the program's; 127 when it could not be started, 128 + N when signal N ended it
    double seconds = 0.0;  // wall time from its start to its end
};

struct StageJobEvents {
    std::function<void(const StageJob&)> started;
    std::function<void(const StageJob&, const StageJobEnd&)> ended;
    std::function<void()> tick;  // about every tick_seconds while any job runs
    double tick_seconds = 0.25;
};

// Runs every job, at most `max_parallel` at once; among the jobs whose
// predecessors have ended, the earliest in the list starts first. Returns
// each job's end, in the jobs' order. Throws std::invalid_argument naming
// the job when one waits for a name not in the list, or for itself through
// a cycle. The events are called from the calling thread.
std::vector<StageJobEnd> run_stage_jobs(const std::vector<StageJob>& jobs, int max_parallel,
                                        const StageJobEvents& events = {});

// Starts `argv` (argv[0] looked up on PATH) with its stdout sent to
// `stdout_file` and its stderr to `stderr_file`, or left as this process's
// when that is empty. Returns its process id, or -1 with errno's reason in
// `error` when it cannot start.
int start_program(const std::vector<std::string>& argv, const std::filesystem::path& stdout_file,
                  const std::filesystem::path& stderr_file, int* error = nullptr);

// The lines appended to a file since the last call (whole lines only: a
// line still being written waits for its newline). A missing file has none.
class FileFollower {
public:
    explicit FileFollower(std::filesystem::path path) : m_path(std::move(path)) {}
    std::vector<std::string> new_lines();

private:
    std::filesystem::path m_path;
    std::uintmax_t m_offset = 0;
    std::string m_partial;
};

}  // namespace flowvid::cli
