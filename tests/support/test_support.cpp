#include "test_support.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace flowvid::testing {
namespace fs = std::filesystem;

std::string test_data(const std::string& relative) { return std::string(FLOWVID_TEST_DATA_DIR) + "/" + relative; }
std::string shared_path(const std::string& relative) { return std::string(FLOWVID_SHARED_DIR) + "/" + relative; }
std::string source_path(const std::string& relative) { return std::string(FLOWVID_SOURCE_DIR) + "/" + relative; }

std::string scratch_dir(const std::string& name) {
    fs::path dir = fs::path(FLOWVID_BINARY_DIR) / "test-scratch" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir.string();
}

void write_text(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
}

std::string validation_messages(const std::function<void()>& action) {
    try {
        action();
    } catch (const ValidationError& error) {
        std::string text;
        for (const Problem& problem : error.problems()) text += problem.to_string() + "\n";
        return text;
    } catch (const std::exception& error) {
        ADD_FAILURE() << "expected a ValidationError, got: " << error.what();
        return {};
    }
    ADD_FAILURE() << "expected a ValidationError, nothing was thrown";
    return {};
}

}  // namespace flowvid::testing
