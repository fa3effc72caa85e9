#include "cli_runner.hpp"

#include "test_support.hpp"

#include <cstdlib>
#include <sys/wait.h>
#include <unistd.h>

namespace flowvid::testing {

std::string shell_quote(const std::string& text) {
    std::string quoted = "'";
    for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return quoted + "'";
}

CliResult run_flowvid(const std::vector<std::string>& arguments, const std::string& working_dir) {
    static int counter = 0;
    // Unique per process and call: ctest runs test processes in parallel.
    const std::string dir = scratch_dir("cli_runner_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    std::string command = working_dir.empty() ? std::string() : "cd " + shell_quote(working_dir) + " && ";
    command += shell_quote(FLOWVID_CLI_PATH);
    for (const std::string& argument : arguments) command += " " + shell_quote(argument);
    command += " >" + shell_quote(dir + "/out") + " 2>" + shell_quote(dir + "/err") + " </dev/null";
    const int status = std::system(command.c_str());
    CliResult result;
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    result.out = read_text(dir + "/out");
    result.err = read_text(dir + "/err");
    return result;
}

}  // namespace flowvid::testing
