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

// Arguments are quoted for the shell; stdout and stderr are captured separately.
CliResult run_flowvid(const std::vector<std::string>& arguments);

}  // namespace flowvid::testing
