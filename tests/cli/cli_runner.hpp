#pragma once
// Runs the built `flowvid` binary the way a user or a farm script does.

#include <string>
#include <vector>

namespace flowvid::testing {

struct CliResult {
    int exit_code = -1;
    std::string out;  // stdout
    std::string err;  // stderr
};

// Arguments are quoted for the shell; stdout and stderr are captured
// separately. `working_dir`: where it runs (empty: the test's own).
// `text` as one shell word.
std::string shell_quote(const std::string& text);

CliResult run_flowvid(const std::vector<std::string>& arguments, const std::string& working_dir = {});

}  // namespace flowvid::testing
