#pragma once
// Helpers shared by flowvid's tests: where data lives, scratch folders, and
// assertions on flowvid::Error messages.

#include "flowvid/error.hpp"

#include <functional>
#include <string>

namespace flowvid::testing {

std::string test_data(const std::string& relative);     // tests/data/<relative>
std::string shared_path(const std::string& relative);   // ../shared/<relative>
std::string source_path(const std::string& relative);   // repository root/<relative>

// A fresh empty folder under the build tree, removed and recreated per call.
std::string scratch_dir(const std::string& name);
void write_text(const std::string& path, const std::string& text);
std::string read_text(const std::string& path);

// True when `part` occurs in `text` (messages name the file, field and fix).
inline bool mentions(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Runs `action`, expects a flowvid::ValidationError and returns its problems
// joined one per line (what a user would read).
std::string validation_messages(const std::function<void()>& action);

}  // namespace flowvid::testing
