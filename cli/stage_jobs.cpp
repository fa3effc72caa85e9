#include "stage_jobs.hpp"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <fstream>
#include <map>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace flowvid::cli {
namespace {

using Clock = std::chrono::steady_clock;

int exit_code_of(int status) {
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
    return 1;
}

// Throws when a job waits for an unknown name or, through others, for itself.
void check_order(const std::vector<StageJob>& jobs) {
    std::map<std::string, std::size_t> index;
    for (std::size_t i = 0; i < jobs.size(); ++i) index[jobs[i].name] = i;
    for (const StageJob& job : jobs)
        for (const std::string& name : job.after)
            if (!index.count(name))
                throw std::invalid_argument("job '" + job.name + "' waits for '" + name + "', which is not among the jobs");
    // Depth-first search for a cycle: 0 unseen, 1 on the path, 2 done.
    std::vector<int> state(jobs.size(), 0);
    std::function<void(std::size_t)> visit = [&](std::size_t i) {
        state[i] = 1;
        for (const std::string& name : jobs[i].after) {
            const std::size_t j = index[name];
            if (state[j] == 1) throw std::invalid_argument("job '" + jobs[i].name + "' waits for itself through '" + name + "'");
            if (state[j] == 0) visit(j);
        }
        state[i] = 2;
    };
    for (std::size_t i = 0; i < jobs.size(); ++i)
        if (state[i] == 0) visit(i);
}

}  // namespace

int start_program(const std::vector<std::string>& argv_text, const std::filesystem::path& stdout_file,
                  const std::filesystem::path& stderr_file, int* error) {
    std::vector<std::string> text = argv_text;
    std::vector<char*> argv;
    for (std::string& a : text) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, stdout_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (!stderr_file.empty())
        posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t child = -1;
    const int spawned = argv.size() > 1 ? posix_spawnp(&child, argv[0], &actions, nullptr, argv.data(), environ) : ENOENT;
    posix_spawn_file_actions_destroy(&actions);
    if (error) *error = spawned;
    return spawned == 0 ? child : -1;
}

std::vector<StageJobEnd> run_stage_jobs(const std::vector<StageJob>& jobs, int max_parallel, const StageJobEvents& events) {
    check_order(jobs);
    max_parallel = std::max(1, max_parallel);
    enum class State { waiting, running, ended };
    std::vector<State> state(jobs.size(), State::waiting);
    std::vector<pid_t> pid(jobs.size(), -1);
    std::vector<Clock::time_point> began(jobs.size());
    std::vector<StageJobEnd> ends(jobs.size());
    const auto has_ended = [&](const std::string& name) {
        for (std::size_t i = 0; i < jobs.size(); ++i)
            if (jobs[i].name == name) return state[i] == State::ended;
        return false;
    };
    const auto finish = [&](std::size_t i, int exit_code) {
        state[i] = State::ended;
        ends[i] = {exit_code, std::chrono::duration<double>(Clock::now() - began[i]).count()};
        if (events.ended) events.ended(jobs[i], ends[i]);
    };
    // The first job in list order that may start now, or jobs.size().
    const auto next_ready = [&] {
        std::size_t i = 0;
        while (i < jobs.size() && (state[i] != State::waiting ||
                                   !std::all_of(jobs[i].after.begin(), jobs[i].after.end(), has_ended)))
            ++i;
        return i;
    };
    for (;;) {
        int running = static_cast<int>(std::count(state.begin(), state.end(), State::running));
        for (std::size_t i; running < max_parallel && (i = next_ready()) < jobs.size();) {
            began[i] = Clock::now();
            state[i] = State::running;
            if (events.started) events.started(jobs[i]);
            pid[i] = start_program(jobs[i].argv, jobs[i].stdout_file, jobs[i].stderr_file);
            if (pid[i] < 0) finish(i, 127);  // its end may release its followers: the next search sees them
            else ++running;
        }
        if (running == 0) break;  // all ended (check_order rules out waiting forever)
        // Wait a tick, then collect whatever ended.
        const auto deadline = Clock::now() + std::chrono::duration<double>(events.tick_seconds);
        bool any_ended = false;
        while (!any_ended && Clock::now() < deadline) {
            for (std::size_t i = 0; i < jobs.size(); ++i) {
                if (state[i] != State::running) continue;
                int status = 0;
                const pid_t done = waitpid(pid[i], &status, WNOHANG);
                if (done == pid[i] || (done < 0 && errno != EINTR)) {
                    finish(i, done == pid[i] ? exit_code_of(status) : 1);
                    any_ended = true;
                }
            }
            if (!any_ended) std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        if (events.tick) events.tick();
    }
    return ends;
}

std::vector<std::string> FileFollower::new_lines() {
    std::vector<std::string> lines;
    std::ifstream in(m_path, std::ios::binary);
    if (!in) return lines;
    in.seekg(static_cast<std::streamoff>(m_offset));
    std::string chunk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    m_offset += chunk.size();
    m_partial += chunk;
    std::size_t start = 0;
    for (std::size_t end; (end = m_partial.find('\n', start)) != std::string::npos; start = end + 1)
        lines.push_back(m_partial.substr(start, end - start));
    m_partial.erase(0, start);
    return lines;
}

}  // namespace flowvid::cli
