// flowvid: command-line entry point. Parses the command line, runs one
// command, and turns errors into the documented exit codes.

#include "command.hpp"
#include "output.hpp"

#include "flowvid/error.hpp"
#include "flowvid/formats/capture.hpp"
#include "flowvid/version.hpp"

#include <csignal>
#include <iostream>

namespace flowvid::cli {

std::vector<Command>& command_registry() {
    static std::vector<Command> commands;
    return commands;
}

RegisterCommand::RegisterCommand(Command command) { command_registry().push_back(std::move(command)); }

namespace {

constexpr const char* kFooter = R"(Exit codes:
  0    success
  1    failure (the work could not be done)
  2    usage error (unknown command or option)
  3    invalid input (a file failed validation; every problem is listed)
  4    I/O error (missing file, unwritable folder)
  130  interrupted

Results go to stdout; logs, warnings and progress go to stderr.
Run 'flowvid help <command>' for a command's options and examples.)";

int run(int argc, char** argv) {
    CLI::App app{"flowvid " + flowvid::version() +
                 ": realistic animation learned from video.\n"
                 "Fits cloth and rigid-body simulators to footage, saves portable fabric presets,\n"
                 "and synthesizes and edits flow-based video (waterfalls, smoke, fire).",
                 "flowvid"};
    app.footer(kFooter);
    app.set_version_flag("--version", "flowvid " + flowvid::version());
    app.require_subcommand(0, 1);
    // Global flags anywhere on the line: `flowvid synth ... --progress json`
    // as well as `flowvid --progress json synth ...` (commands inherit this).
    app.fallthrough();

    GlobalOptions options;
    app.add_option("--progress", options.progress,
                   "progress on stderr: auto (a bar on a terminal), json (one JSON event per line), none")
        ->check(CLI::IsMember({"auto", "json", "none"}))
        ->capture_default_str();
    app.add_flag("-q,--quiet", options.quiet, "no progress and no informational logs");
    bool allow_outside_paths = false;
    app.add_flag("--allow-outside-paths", allow_outside_paths,
                 "let captures name files outside their folder (../x, absolute paths); off by default so that "
                 "a capture from elsewhere cannot make flowvid read other files");

    std::sort(command_registry().begin(), command_registry().end(),
              [](const Command& a, const Command& b) { return a.name < b.name; });
    struct Parsed {
        CLI::App* app;
        const Command* command;
        CommandRunner run;
    };
    std::vector<Parsed> subcommands;
    for (const Command& command : command_registry()) {
        CLI::App* sub = app.add_subcommand(command.name, command.summary);
        subcommands.push_back({sub, &command, command.setup(*sub)});
    }

    // `flowvid help [command words]`, e.g. `flowvid help fit cloth`
    std::vector<std::string> help_topic;
    CLI::App* help = app.add_subcommand("help", "show help for flowvid or for one command (e.g. flowvid help fit cloth)");
    help->add_option("command", help_topic, "the command to explain, as you would type it");

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return kExitUsage;
    }

    formats::allow_capture_paths_outside_folder(allow_outside_paths);

    if (help->parsed()) {
        // Walk the words down the command tree: "fit cloth" is fit's subcommand cloth.
        const CLI::App* topic = &app;
        std::string matched;  // the words walked so far
        for (const std::string& word : help_topic) {
            const CLI::App* next = nullptr;
            for (const CLI::App* sub : topic->get_subcommands([](const CLI::App*) { return true; }))
                if (sub->get_name() == word) next = sub;
            const std::string words = matched.empty() ? word : matched + " " + word;
            if (next == nullptr) {
                std::cerr << "flowvid: no command '" << words << "' (run 'flowvid help" << (matched.empty() ? "" : " " + matched)
                          << "' for the list)\n";
                return kExitUsage;
            }
            topic = next;
            matched = words;
        }
        // Formatted directly: App::help() would show the parsed `help`
        // subcommand's own help instead. The usage line names the whole
        // command ("flowvid fit cloth").
        std::cout << topic->get_formatter()->make_help(topic, matched.empty() ? "flowvid" : "flowvid " + matched,
                                                        CLI::AppFormatMode::Normal);
        return kExitOk;
    }
    for (const Parsed& sub : subcommands)
        if (sub.app->parsed()) {
            if (!outputs_spare_inputs(*sub.app)) return kExitUsage;
            return sub.run(options);
        }

    std::cout << app.help();
    return kExitUsage;
}

}  // namespace
}  // namespace flowvid::cli

int main(int argc, char** argv) {
    using namespace flowvid::cli;
    try {
        return run(argc, argv);
    } catch (const flowvid::Cancelled&) {  // Ctrl-C through a command's flowvid::Progress
        log_message("interrupted");
        return kExitInterrupted;
    } catch (const flowvid::ValidationError& error) {
        print_problems(error.problems());
        return kExitInvalidInput;
    } catch (const flowvid::UsageError& error) {
        log_message(std::string("error: ") + error.what());
        return kExitUsage;
    } catch (const flowvid::IoError& error) {
        log_message(std::string("error: ") + error.what());
        return kExitIoError;
    } catch (const flowvid::Error& error) {
        log_message(std::string("error: ") + error.what());
        return kExitFailure;
    } catch (const std::exception& error) {
        log_message(std::string("error: ") + error.what());
        return kExitFailure;
    }
}
