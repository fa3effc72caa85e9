#include "flowvid/error.hpp"

#include <algorithm>

namespace flowvid {

std::string Problem::to_string() const {
    std::string text;
    if (severity == Severity::warning) text += "warning: ";
    // A problem with the command line rather than a file names neither.
    if (!file.empty()) text += file + ": ";
    if (!field.empty()) text += field + ": ";
    text += message;
    if (!fix.empty()) text += " (fix: " + fix + ")";
    return text;
}

namespace {
std::string summarise(const std::vector<Problem>& problems) {
    std::string text;
    for (const Problem& problem : problems) {
        if (problem.severity != Problem::Severity::error) continue;
        if (!text.empty()) text += "\n";
        text += problem.to_string();
    }
    return text;
}

std::string first_file(const std::vector<Problem>& problems) {
    return problems.empty() ? std::string() : problems.front().file;
}
}  // namespace

Error::Error(std::string file, std::string field, std::string message, std::string fix)
    : std::runtime_error(Problem{Problem::Severity::error, file, field, message, fix}.to_string()),
      m_file(std::move(file)),
      m_field(std::move(field)),
      m_message(std::move(message)),
      m_fix(std::move(fix)) {}

Error::Error(PreformattedTag, const std::string& what, std::string file)
    : std::runtime_error(what), m_file(std::move(file)), m_message(what) {}

ValidationError::ValidationError(std::vector<Problem> problems)
    : Error(PreformattedTag{}, summarise(problems), first_file(problems)), m_problems(std::move(problems)) {}

void Diagnostics::add(Problem problem) {
    // A hostile or badly broken file can have millions of problems; listing
    // them all helps nobody, and would take as long as the file is large.
    if (m_problems.size() < kMaxProblemsListed) {
        m_problems.push_back(std::move(problem));
        return;
    }
    ++m_problems_not_listed;
    const bool first_overflow = m_problems_not_listed == 1;
    if (first_overflow)
        m_problems.push_back({problem.severity, m_file, "", "", "fix the problems listed and check the file again"});
    // A dropped error keeps the file refused.
    if (problem.severity == Problem::Severity::error) m_problems.back().severity = Problem::Severity::error;
    m_problems.back().message = std::to_string(m_problems_not_listed) + " more problems are not listed";
}

void Diagnostics::error(std::string field, std::string message, std::string fix) {
    add({Problem::Severity::error, m_file, std::move(field), std::move(message), std::move(fix)});
}

void Diagnostics::warning(std::string field, std::string message, std::string fix) {
    add({Problem::Severity::warning, m_file, std::move(field), std::move(message), std::move(fix)});
}

void Diagnostics::merge(const std::vector<Problem>& problems) {
    for (const Problem& problem : problems) add(problem);
}

bool Diagnostics::has_errors() const {
    return std::any_of(m_problems.begin(), m_problems.end(),
                       [](const Problem& p) { return p.severity == Problem::Severity::error; });
}

std::vector<Problem> Diagnostics::warnings() const {
    std::vector<Problem> result;
    for (const Problem& p : m_problems)
        if (p.severity == Problem::Severity::warning) result.push_back(p);
    return result;
}

void Diagnostics::throw_if_errors() const {
    if (has_errors()) throw ValidationError(m_problems);
}

}  // namespace flowvid
