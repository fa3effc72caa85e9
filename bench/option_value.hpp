#pragma once
// The plain benches' (not Google Benchmark's) command-line parsing.

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

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

// A comma-separated option value's items, empty ones skipped ("16,24,48").
inline std::vector<std::string> comma_list(const std::string& text) {
    std::vector<std::string> items;
    std::stringstream list(text);
    for (std::string item; std::getline(list, item, ',');)
        if (!item.empty()) items.push_back(item);
    return items;
}

}  // namespace flowvid::bench
