#pragma once
// Results go to stdout; logs, warnings and progress to stderr.

#include "command.hpp"
#include "flowvid/error.hpp"
#include "flowvid/progress.hpp"

#include <atomic>
#include <nlohmann/json.hpp>

#include <memory>
#include <string>
#include <vector>

namespace flowvid::cli {

void log_message(const std::string& text);             // stderr, one line
void print_problems(const std::vector<Problem>& problems);  // stderr, one line each
// A JSON summary as indented "key: value" lines for people.
std::string human_readable(const nlohmann::json& value, int indent = 0);

// Progress on stderr: a bar on a terminal ("task: stage"), JSON lines with
// --progress=json ({"event": "progress", "task", "stage" when there is one,
// "fraction", "detail"}).
class ProgressBar {
public:
    ProgressBar(const GlobalOptions& options, std::string task, std::string stage = {});
    void update(double fraction, const std::string& detail = {});
    void done();

private:
    std::string m_task;
    std::string m_stage;
    std::string m_mode;
    int m_last_percent = -1;
};

// Refuses a command line whose outputs would destroy its inputs (--out equal
// to --preset, or to a capture folder's capture.json) or write one file twice
// (--out X --vat X). Looks at the parsed (sub)command's options: --out,
// --vat, --report, --dense-out, --series, --auto-lines and OUT are outputs;
// every other value naming an existing file or folder is an input. Returns
// false after printing the problem with its fix.
bool outputs_spare_inputs(const CLI::App& command);

// --out, where every command writes its output; `old_name` (e.g.
// "--report") stays as a hidden alias that warns it is now --out.
CLI::Option* add_out_option(CLI::App& app, std::string& out, const std::string& help, const std::string& old_name = {});

// Whether two paths name one file, whether or not it exists yet ("a/../x"
// and "x", a symlink and its target).
bool same_file(const std::string& a, const std::string& b);

// A check for a file option (`->check(...)`): the name must end in one of
// `endings` (any case), e.g. {".exr"}, so a bank is not written as an EXR
// file named "bank.png". `what` says what the file is ("a particle bank, an
// OpenEXR file"), `example` a good name.
CLI::Validator file_name_ending(std::vector<std::string> endings, const std::string& what, const std::string& example);

// Ctrl-C during long work: while one of these lives, SIGINT sets a flag the
// work's progress callback polls (so it can stop cleanly and write nothing)
// instead of killing the process. The previous handler comes back on exit.
class InterruptWatch {
public:
    InterruptWatch();
    ~InterruptWatch();
    InterruptWatch(const InterruptWatch&) = delete;
    InterruptWatch& operator=(const InterruptWatch&) = delete;
    bool requested() const;
    // For solvers that poll a flag inside long steps (cloth::SimulationSettings::cancel).
    const std::atomic<bool>* flag() const;
};

// The library's flowvid::Progress on the terminal: a ProgressBar per stage
// ("synth: render"), log lines in the log (each ends the bar it
// interrupts), and Ctrl-C as cancel while the object lives.
class TerminalProgress {
public:
    TerminalProgress(const GlobalOptions& options, std::string task);
    ~TerminalProgress();  // finish()
    // Ends the open bar (before a summary goes to stdout).
    void finish();
    TerminalProgress(const TerminalProgress&) = delete;
    TerminalProgress& operator=(const TerminalProgress&) = delete;
    // Valid while this object lives.
    flowvid::Progress callback();
    bool interrupted() const { return m_interrupt.requested(); }

private:
    const GlobalOptions& m_options;
    std::string m_task;
    std::string m_stage;
    std::unique_ptr<ProgressBar> m_bar;
    InterruptWatch m_interrupt;
};

}  // namespace flowvid::cli
