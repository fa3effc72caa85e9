#pragma once
// How a `flowvid <command>` plugs into the tool: each commands/<name>.cpp
// registers one Command. main.cpp only dispatches and maps errors to exit codes.

#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace flowvid::cli {

// Documented exit codes (README, `flowvid --help`).
enum ExitCode : int {
    kExitOk = 0,
    kExitFailure = 1,
    kExitUsage = 2,
    kExitInvalidInput = 3,
    kExitIoError = 4,
    kExitInterrupted = 130,
};

// Options every command shares.
struct GlobalOptions {
    std::string progress = "auto";  // auto (bar on a terminal), json (one event per line), none
    bool quiet = false;
};

using CommandRunner = std::function<int(const GlobalOptions&)>;

struct Command {
    std::string name;
    std::string summary;
    // Adds the command's options and help to its subcommand and returns the
    // function that runs it with the parsed values (it owns their storage).
    std::function<CommandRunner(CLI::App&)> setup;
};

// Commands register themselves from static initialisers in commands/*.cpp.
std::vector<Command>& command_registry();
struct RegisterCommand {
    explicit RegisterCommand(Command command);
};

}  // namespace flowvid::cli
