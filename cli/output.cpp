#include "output.hpp"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <unistd.h>

namespace flowvid::cli {

void log_message(const std::string& text) { std::cerr << text << '\n'; }

void print_problems(const std::vector<Problem>& problems) {
    for (const Problem& problem : problems) std::cerr << problem.to_string() << '\n';
}

std::string human_readable(const nlohmann::json& value, int indent) {
    std::ostringstream text;
    const std::string pad(static_cast<std::size_t>(indent) * 2, ' ');
    if (value.is_object()) {
        for (auto it = value.begin(); it != value.end(); ++it) {
            const nlohmann::json& child = it.value();
            const bool scalar_list = child.is_array() && std::all_of(child.begin(), child.end(), [](const nlohmann::json& e) {
                                         return e.is_primitive();
                                     });
            if (child.is_primitive() || scalar_list) {
                text << pad << it.key() << ": ";
                if (child.is_string()) text << child.get<std::string>();
                else if (scalar_list) {
                    for (std::size_t i = 0; i < child.size(); ++i)
                        text << (i ? ", " : "") << (child[i].is_string() ? child[i].get<std::string>() : child[i].dump());
                } else text << child.dump();
                text << '\n';
            } else {
                text << pad << it.key() << ":\n" << human_readable(child, indent + 1);
            }
        }
    } else if (value.is_array()) {
        for (const nlohmann::json& element : value) {
            text << pad << "-\n" << human_readable(element, indent + 1);
        }
    } else {
        text << pad << (value.is_string() ? value.get<std::string>() : value.dump()) << '\n';
    }
    return text.str();
}

ProgressBar::ProgressBar(const GlobalOptions& options, std::string task, std::string stage)
    : m_task(std::move(task)), m_stage(std::move(stage)) {
    m_mode = options.progress;
    if (options.quiet) m_mode = "none";
    if (m_mode == "auto") m_mode = ::isatty(STDERR_FILENO) ? "bar" : "none";
}

void ProgressBar::update(double fraction, const std::string& detail) {
    const int percent = static_cast<int>(fraction * 100.0 + 0.5);
    if (percent == m_last_percent) return;
    m_last_percent = percent;
    if (m_mode == "json") {
        nlohmann::json event = {{"event", "progress"}, {"task", m_task}, {"fraction", fraction}};
        if (!m_stage.empty()) event["stage"] = m_stage;
        if (!detail.empty()) event["detail"] = detail;
        std::cerr << event.dump() << std::endl;
    } else if (m_mode == "bar") {
        const int width = 30;
        const int filled = percent * width / 100;
        std::cerr << '\r' << m_task << (m_stage.empty() ? "" : ": " + m_stage) << " [" << std::string(filled, '#') << std::string(width - filled, ' ') << "] "
                  << percent << "% " << detail << std::flush;
    }
}

void ProgressBar::done() {
    if (m_mode == "json") {
        nlohmann::json event = {{"event", "done"}, {"task", m_task}};
        if (!m_stage.empty()) event["stage"] = m_stage;
        std::cerr << event.dump() << std::endl;
    }
    else if (m_mode == "bar") std::cerr << '\n';
}

namespace {
bool is_output_option(const std::string& name) {
    for (const char* output : {"--out", "--vat", "--report", "--dense-out", "--series", "--auto-lines", "OUT"})
        if (name == output) return true;
    return false;
}

// One spelling per file, whether or not it exists yet, so that "a/../x" and
// "x" (or a symlink and its target) compare equal.
std::filesystem::path identity(const std::string& path) {
    std::error_code ec;
    std::filesystem::path canonical = std::filesystem::weakly_canonical(path, ec);
    return ec ? std::filesystem::path(path).lexically_normal() : canonical;
}
}  // namespace

CLI::Option* add_out_option(CLI::App& app, std::string& out, const std::string& help, const std::string& old_name) {
    CLI::Option* option = app.add_option("--out", out, help);
    if (!old_name.empty())
        app.add_option(old_name, out, "")
            ->group("")  // hidden: old scripts keep working
            ->excludes(option)
            ->each([old_name](const std::string&) {
                log_message("warning: " + old_name + " is now --out (" + old_name + " will be removed)");
            });
    return option;
}

bool outputs_spare_inputs(const CLI::App& command) {
    namespace fs = std::filesystem;
    const CLI::App* leaf = &command;
    while (!leaf->get_subcommands().empty()) leaf = leaf->get_subcommands().front();
    struct Named {
        std::string option;
        std::string value;
        fs::path path;
    };
    std::vector<Named> outputs, inputs;
    for (const CLI::Option* option : leaf->get_options()) {
        for (const std::string& value : option->results()) {
            if (value.empty()) continue;
            if (is_output_option(option->get_name())) {
                outputs.push_back({option->get_name(), value, identity(value)});
                continue;
            }
            std::error_code ec;
            const fs::file_status status = fs::status(value, ec);
            if (ec || !fs::exists(status)) continue;  // not a path: a number, a name
            inputs.push_back({option->get_name(), value, identity(value)});
            // A capture is named by its folder; its capture.json is the file at stake.
            if (fs::is_directory(status))
                inputs.push_back({option->get_name(), (fs::path(value) / "capture.json").string(),
                                  identity((fs::path(value) / "capture.json").string())});
        }
    }
    for (std::size_t i = 0; i < outputs.size(); ++i) {
        for (std::size_t j = 0; j < i; ++j)
            if (outputs[i].path == outputs[j].path) {
                log_message("error: " + outputs[j].option + " and " + outputs[i].option + " both name " +
                            outputs[i].value + "; one would overwrite the other (fix: give each output its own file)");
                return false;
            }
        for (const Named& input : inputs)
            if (outputs[i].path == input.path) {
                log_message("error: " + outputs[i].option + " " + outputs[i].value + " is the input " + input.option +
                            " " + input.value + "; writing it would destroy it (fix: write to another file)");
                return false;
            }
    }
    return true;
}

bool same_file(const std::string& a, const std::string& b) { return identity(a) == identity(b); }

CLI::Validator file_name_ending(std::vector<std::string> endings, const std::string& what, const std::string& example) {
    std::string listed;
    for (const std::string& ending : endings) listed += (listed.empty() ? "" : " or ") + ending;
    return CLI::Validator(
        [endings, what, example, listed](std::string& name) -> std::string {
            std::string lower = name;
            std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
            for (const std::string& ending : endings)
                if (lower.size() >= ending.size() && lower.compare(lower.size() - ending.size(), ending.size(), ending) == 0)
                    return {};
            return name + ": this writes " + what + "; name it " + listed + " (e.g. " + example + ")";
        },
        "FILE" + listed, "file_name_ending");
}

namespace {
std::atomic<bool> g_interrupt_requested{false};
void on_interrupt(int) { g_interrupt_requested = true; }
using SignalHandler = void (*)(int);
SignalHandler g_previous_handler = SIG_DFL;
}  // namespace

InterruptWatch::InterruptWatch() {
    g_interrupt_requested = false;
    g_previous_handler = std::signal(SIGINT, on_interrupt);
}
InterruptWatch::~InterruptWatch() { std::signal(SIGINT, g_previous_handler); }
bool InterruptWatch::requested() const { return g_interrupt_requested.load(); }
const std::atomic<bool>* InterruptWatch::flag() const { return &g_interrupt_requested; }

TerminalProgress::TerminalProgress(const GlobalOptions& options, std::string task)
    : m_options(options), m_task(std::move(task)) {}

TerminalProgress::~TerminalProgress() { finish(); }

void TerminalProgress::finish() {
    if (m_bar) m_bar->done();
    m_bar.reset();
    m_stage.clear();
}

flowvid::Progress TerminalProgress::callback() {
    return [this](const ProgressReport& report) {
        if (report.fraction < 0.0) {  // a line for the log ends the bar it interrupts
            finish();
            log_message(report.message);
            return true;
        }
        if (!m_bar || report.stage != m_stage) {
            if (m_bar) m_bar->done();
            m_bar = std::make_unique<ProgressBar>(m_options, m_task, report.stage);
            m_stage = report.stage;
        }
        m_bar->update(report.fraction, report.message);
        return !m_interrupt.requested();
    };
}

}  // namespace flowvid::cli
