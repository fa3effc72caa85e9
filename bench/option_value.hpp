#pragma once
// The plain benches' (not Google Benchmark's) command-line parsing.

#include <cstdio>
#include <cstdlib>
#include <string>

namespace flowvid::bench {

// The value after the option argv[i], advancing i to it; exits with status 2
// when the option is the last argument.
inline std::string option_value(int argc, char** argv, int& i) {
    if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", argv[i]);
        std::exit(2);
    }
    return argv[++i];
}

}  // namespace flowvid::bench
