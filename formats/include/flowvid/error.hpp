#pragma once
// The one exception family for user-facing mistakes. Every flowvid::Error says
// where it happened (file and, when known, the field inside the file) and what
// to do about it, so that a message alone lets a user fix the input.

#include <stdexcept>
#include <string>
#include <vector>

namespace flowvid {

// One problem found in an input: which file, which field (JSON pointer such as
// "/parameters/bend_stiffness_N_m/value", an EXR attribute, an SVG element id),
// what is wrong and how to fix it.
struct Problem {
    enum class Severity { warning, error };
    Severity severity = Severity::error;
    std::string file;
    std::string field;
    std::string message;
    std::string fix;

    // "file: field: message (fix: ...)" or "warning: ..." for warnings.
    std::string to_string() const;
};

class Error : public std::runtime_error {
public:
    Error(std::string file, std::string field, std::string message, std::string fix = {});
    const std::string& file() const { return m_file; }
    const std::string& field() const { return m_field; }
    const std::string& fix() const { return m_fix; }
    // The message alone, without file, field and fix (what() has them all):
    // for turning an Error into a Problem without repeating them.
    const std::string& message() const { return m_message; }

protected:
    struct PreformattedTag {};
    Error(PreformattedTag, const std::string& what, std::string file);

private:
    std::string m_file;
    std::string m_field;
    std::string m_message;
    std::string m_fix;
};

// A file could not be read or written at all (missing, permission, disk full).
class IoError : public Error {
public:
    using Error::Error;
};

// A request lacks something only the user can give (an input not named and
// not recorded anywhere): the fix names the option.
class UsageError : public Error {
public:
    using Error::Error;
};

// A file was read but its content is invalid. Carries every problem found, not
// only the first, so a user fixes them all in one pass.
class ValidationError : public Error {
public:
    explicit ValidationError(std::vector<Problem> problems);
    const std::vector<Problem>& problems() const { return m_problems; }

private:
    std::vector<Problem> m_problems;
};

// Collects the problems of one file while it is validated.
class Diagnostics {
public:
    explicit Diagnostics(std::string file) : m_file(std::move(file)) {}

    void error(std::string field, std::string message, std::string fix = {});
    void warning(std::string field, std::string message, std::string fix = {});
    // Adds problems found in another file (e.g. a mesh referenced by a capture).
    void merge(const std::vector<Problem>& problems);

    const std::string& file() const { return m_file; }
    bool has_errors() const;
    const std::vector<Problem>& problems() const { return m_problems; }
    std::vector<Problem> warnings() const;

    // Throws ValidationError carrying every problem when any is an error.
    void throw_if_errors() const;

    // Problems kept in full; beyond them one error counts the rest.
    static constexpr std::size_t kMaxProblemsListed = 100;

private:
    void add(Problem problem);

    std::string m_file;
    std::vector<Problem> m_problems;
    std::size_t m_problems_not_listed = 0;
};

}  // namespace flowvid
