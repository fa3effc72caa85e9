// Fuzzing in every test suite, with the compiler the project builds with (no
// clang or libFuzzer needed). Deterministic: a fixed seed, the same run each time.
//
//   flowvid_fuzz_replay corpus CORPUS_DIR MUTATIONS_PER_TARGET [TARGET...]
//       every corpus file of every reader, then seeded mutations of them: the
//       structure-aware ones of fuzz/structure_mutator.cpp (deep nesting, odd
//       numbers, entity amplification, many attributes, glb/EXR headers, ...)
//       and byte-level ones (bit flips, truncations, insertions, splices).
//   flowvid_fuzz_replay regressions REGRESSIONS_DIR
//       the inputs of bugs found (fuzz/regressions/<target>/*) and the issue
//       #34 reproducers generated at full size (fuzz/reproducers.cpp), one
//       process each, every one reported.
//   flowvid_fuzz_replay write-generated DIR     writes the generated reproducers as files
//   flowvid_fuzz_replay mutate CORPUS_DIR TARGET COUNT DIR
//       COUNT mutations of the target's corpus as files (for the Python replay)
//   flowvid_fuzz_replay run TARGET FILE...      one input each, in this process (debugging)
//
// Each target (corpus) or case (regressions) runs in a child process with a
// time limit per input (10 s; 30 s for a regression), an address-space limit
// (4 GiB) and a limit of 1 GiB on one allocation, so a crash, a hang, an
// allocation that runs away or an exception other than flowvid::Error is
// reported with the reader, the mutation and the input, and the input is saved under --crash-dir (default
// ./fuzz-crashes) for `flowvid_fuzz_replay run` or a libFuzzer binary.

#include "fuzz_entry_points.hpp"
#include "reproducers.hpp"
#include "structure_mutator.hpp"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <cerrno>
#include <cxxabi.h>
#include <exception>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <new>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <typeinfo>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace flowvid::fuzz;

namespace {

constexpr std::size_t kReplayMaxSize = 256 * 1024;     // largest mutated input
constexpr rlim_t kAddressSpaceLimit = rlim_t(4) << 30;  // per child

Bytes read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// ---- The input being run, for the signal handlers ----------------------------

struct Current {
    const std::uint8_t* data = nullptr;
    std::size_t size = 0;
    char label[512] = {};       // "fabric_json: mutation 17 of seed x (json_nest_deep)"
    char save_path[1024] = {};  // where the input goes when it fails
};
Current g_current;

void set_current(const Bytes& input, const std::string& label, const fs::path& save_path) {
    g_current.data = input.data();
    g_current.size = input.size();
    std::snprintf(g_current.label, sizeof g_current.label, "%s", label.c_str());
    std::snprintf(g_current.save_path, sizeof g_current.save_path, "%s", save_path.c_str());
}

void write_all(int fd, const void* data, std::size_t size) {
    const char* bytes = static_cast<const char*>(data);
    while (size > 0) {
        const ssize_t written = ::write(fd, bytes, size);
        if (written <= 0) return;
        bytes += written;
        size -= static_cast<std::size_t>(written);
    }
}

void write_message(const char* text) { write_all(STDERR_FILENO, text, std::strlen(text)); }

// Async-signal-safe: saves the input and says what it was.
void save_current_input() {
    if (!g_current.data || !g_current.save_path[0]) return;
    const int fd = ::open(g_current.save_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
        write_all(fd, g_current.data, g_current.size);
        ::close(fd);
    }
}

extern "C" void on_fatal_signal(int signal_number) {
    save_current_input();
    write_message("\nFUZZ FAILURE: ");
    write_message(signal_number == SIGALRM ? "timeout (hang or quadratic time)" : strsignal(signal_number));
    write_message(" in ");
    write_message(g_current.label);
    write_message("\n  input saved to ");
    write_message(g_current.save_path);
    write_message("\n");
    std::signal(signal_number, SIG_DFL);
    if (signal_number == SIGALRM) ::_exit(124);
    std::raise(signal_number);
}

void install_handlers() {
    // An alternate stack, so that a stack overflow is reported too.
    static std::unique_ptr<char[]> alternate(new char[1 << 16]);
    stack_t stack{};
    stack.ss_sp = alternate.get();
    stack.ss_size = 1 << 16;
    ::sigaltstack(&stack, nullptr);
    struct sigaction action {};
    action.sa_handler = on_fatal_signal;
    action.sa_flags = SA_ONSTACK;
    sigemptyset(&action.sa_mask);
    for (int signal_number : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGALRM}) ::sigaction(signal_number, &action, nullptr);
}

void limit_address_space() {
    rlimit limit{};
    if (::getrlimit(RLIMIT_AS, &limit) == 0 && (limit.rlim_cur == RLIM_INFINITY || limit.rlim_cur > kAddressSpaceLimit)) {
        limit.rlim_cur = kAddressSpaceLimit;
        ::setrlimit(RLIMIT_AS, &limit);
    }
}

}  // namespace

// One allocation over 1 GiB fails the input, as libFuzzer's -malloc_limit_mb=1024
// does: a reader must not ask for gigabytes because a header says so (throwing
// std::bad_alloc instead could be caught and reported as a problem, hiding it).
// Replacing the global operators covers the libraries too (OpenEXR, tinygltf).
namespace {
constexpr std::size_t kAllocationLimit = std::size_t(1) << 30;
bool g_limit_allocations = false;

void* checked_allocate(std::size_t size) {
    if (size > kAllocationLimit && g_limit_allocations) {
        g_limit_allocations = false;
        char message[128];
        std::snprintf(message, sizeof message, "\nFUZZ FAILURE: one allocation of %zu bytes (over 1 GiB)", size);
        write_message(message);
        std::abort();  // the handler names the input and saves it
    }
    if (void* memory = std::malloc(size ? size : 1)) return memory;
    throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t size) { return checked_allocate(size); }
void* operator new[](std::size_t size) { return checked_allocate(size); }
void operator delete(void* memory) noexcept { std::free(memory); }
void operator delete[](void* memory) noexcept { std::free(memory); }
void operator delete(void* memory, std::size_t) noexcept { std::free(memory); }
void operator delete[](void* memory, std::size_t) noexcept { std::free(memory); }

namespace {

std::string type_name(const std::type_info& type) {
    int status = 0;
    std::unique_ptr<char, void (*)(void*)> name(abi::__cxa_demangle(type.name(), nullptr, nullptr, &status), std::free);
    return status == 0 && name ? name.get() : type.name();
}

// Runs the current input; false (after saying why) when an exception other
// than flowvid's escapes.
bool run_checked(const FuzzTarget& target, const Bytes& input) {
    try {
        fuzz_one_input(target, input.data(), input.size());
        return true;
    } catch (const std::exception& error) {
        save_current_input();
        std::cerr << "\nFUZZ FAILURE: " << type_name(typeid(error)) << " escaped (only flowvid::Error may): "
                  << error.what() << "\n  in " << g_current.label << "\n  input saved to " << g_current.save_path << "\n";
    } catch (...) {
        save_current_input();
        std::cerr << "\nFUZZ FAILURE: a non-std exception escaped in " << g_current.label << "\n  input saved to "
                  << g_current.save_path << "\n";
    }
    return false;
}

// Runs `work` in a child process; returns a description of how it ended ("" = passed).
template <typename Work>
std::string in_child(Work&& work) {
    std::cout.flush();
    std::cerr.flush();
    const pid_t child = ::fork();
    if (child < 0) return "fork failed";
    if (child == 0) {
        install_handlers();
        limit_address_space();
        g_limit_allocations = true;
        const bool passed = work();
        std::cout.flush();
        std::cerr.flush();
        ::_exit(passed ? 0 : 1);
    }
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    // The child's scratch folder (fuzz_entry_points.cpp), left when it was killed.
    std::error_code ec;
    fs::remove_all(fs::temp_directory_path() / ("flowvid-fuzz-" + std::to_string(child)), ec);
    if (WIFEXITED(status)) {
        if (WEXITSTATUS(status) == 0) return "";
        if (WEXITSTATUS(status) == 124) return "timeout";
        return "failed (exit " + std::to_string(WEXITSTATUS(status)) + ")";
    }
    if (WIFSIGNALED(status)) return std::string("crashed (") + strsignal(WTERMSIG(status)) + ")";
    return "failed";
}

// ---- Byte-level mutations (the structure-aware ones are shared) ---------------

Bytes byte_mutate(const Bytes& input, MutationRandom& random) {
    Bytes bytes = input;
    const std::size_t edits = 1 + random.below(4);
    for (std::size_t e = 0; e < edits; ++e) {
        const std::size_t size = bytes.size();
        switch (random.below(5)) {
            case 0:  // flip a bit
                if (size) bytes[random.below(size)] ^= static_cast<std::uint8_t>(1u << random.below(8));
                break;
            case 1:  // truncate
                if (size) bytes.resize(random.below(size));
                break;
            case 2: {  // insert an interesting byte
                static const char interesting[] = "\0\xff{}[]\",:-0e9<>/&;!%";
                bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(random.below(size + 1)),
                             static_cast<std::uint8_t>(interesting[random.below(sizeof interesting - 1)]));
                break;
            }
            case 3:  // overwrite with a large number's bytes (sizes in binary headers)
                if (size >= 4) {
                    const std::size_t at = random.below(size - 3);
                    for (std::size_t i = 0; i < 4; ++i) bytes[at + i] = 0xff;
                }
                break;
            default:  // duplicate a slice
                if (size > 2) {
                    const std::size_t from = random.below(size);
                    const std::size_t length = std::min<std::size_t>(random.below(64), size - from);
                    const Bytes slice(bytes.begin() + static_cast<std::ptrdiff_t>(from),
                                      bytes.begin() + static_cast<std::ptrdiff_t>(from + length));
                    bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(random.below(size)), slice.begin(), slice.end());
                }
        }
    }
    return bytes;
}

// One mutated input: structure-aware (3 in 4), byte-level (1 in 4), or both.
Bytes mutated_input(const FuzzTarget& target, const std::vector<Bytes>& seeds, MutationRandom& random,
                    std::size_t& seed_index, std::string& how) {
    seed_index = random.below(seeds.size());
    Bytes input = seeds[seed_index];
    how.clear();
    const std::size_t choice = random.below(4);
    if (choice != 0) how = structure_mutate(input, target.kind, kReplayMaxSize, random.next());
    if (choice == 0 || choice == 3 || how.empty()) {
        input = byte_mutate(input, random);
        how += how.empty() ? "bytes" : "+bytes";
    }
    return input;
}

std::vector<fs::path> files_in(const fs::path& folder) {
    std::vector<fs::path> files;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder, ec))
        if (entry.is_regular_file() && entry.path().filename().string()[0] != '.') files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    return files;
}

// ---- Modes -------------------------------------------------------------------

int replay_corpus(const fs::path& corpus_root, int mutations, const std::vector<std::string>& only,
                  const fs::path& crash_dir) {
    int targets_run = 0, failures = 0;
    for (const FuzzTarget& target : fuzz_targets()) {
        if (!only.empty() && std::find(only.begin(), only.end(), target.name) == only.end()) continue;
        std::vector<Bytes> seeds;
        std::vector<std::string> seed_names;
        for (const fs::path& file : files_in(corpus_root / target.name)) {
            seeds.push_back(read_bytes(file));
            seed_names.push_back(file.filename().string());
        }
        if (seeds.empty()) {
            std::cerr << target.name << ": no corpus in " << (corpus_root / target.name) << "\n";
            ++failures;
            continue;
        }
        ++targets_run;
        const auto start = std::chrono::steady_clock::now();
        const std::string outcome = in_child([&] {
            for (std::size_t i = 0; i < seeds.size(); ++i) {
                set_current(seeds[i], target.name + ": corpus file " + seed_names[i],
                            crash_dir / (target.name + "-corpus-" + seed_names[i]));
                ::alarm(10);
                if (!run_checked(target, seeds[i])) return false;
            }
            // One stream per target: adding a target does not change the others' inputs.
            MutationRandom random(20261121u ^ std::hash<std::string>{}(target.name));
            for (int m = 0; m < mutations; ++m) {
                std::size_t seed_index = 0;
                std::string how;
                const Bytes input = mutated_input(target, seeds, random, seed_index, how);
                set_current(input,
                            target.name + ": mutation " + std::to_string(m) + " of " + seed_names[seed_index] + " (" + how + ")",
                            crash_dir / (target.name + "-mutation-" + std::to_string(m)));
                ::alarm(10);
                if (!run_checked(target, input)) return false;
            }
            ::alarm(0);
            return true;
        });
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::cerr << target.name << ": " << seeds.size() << " corpus files + " << mutations << " mutations, " << seconds
                  << " s" << (outcome.empty() ? "" : ": " + outcome) << "\n";
        if (!outcome.empty()) ++failures;
    }
    if (failures) {
        std::cout << "fuzz replay: " << failures << " target(s) FAILED (inputs in " << crash_dir << ")\n";
        return 1;
    }
    std::cout << "fuzz replay: " << targets_run << " targets, no crash, hang or stray exception\n";
    return targets_run > 0 ? 0 : 1;
}

int replay_regressions(const fs::path& root, const fs::path& crash_dir) {
    struct Case {
        const FuzzTarget* target;
        std::string name;
        std::string what;
        Bytes bytes;
    };
    std::vector<Case> cases;
    for (const FuzzTarget& target : fuzz_targets())
        for (const fs::path& file : files_in(root / target.name))
            cases.push_back({&target, target.name + "/" + file.filename().string(), "", read_bytes(file)});
    for (Reproducer& reproducer : generated_reproducers()) {
        const FuzzTarget* target = find_fuzz_target(reproducer.target);
        if (!target) continue;
        cases.push_back({target, reproducer.target + "/" + reproducer.name, reproducer.what, std::move(reproducer.bytes)});
    }
    // Target folders that no target reads are a mistake (a renamed target).
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(root, ec))
        if (entry.is_directory() && !find_fuzz_target(entry.path().filename().string()))
            std::cerr << "warning: " << entry.path() << " is not a fuzz target's folder\n";
    int failures = 0;
    for (const Case& c : cases) {
        const auto start = std::chrono::steady_clock::now();
        std::string file_name = c.name;
        std::replace(file_name.begin(), file_name.end(), '/', '-');
        const std::string outcome = in_child([&] {
            set_current(c.bytes, "regression " + c.name, crash_dir / ("regression-" + file_name));
            ::alarm(30);
            const bool passed = run_checked(*c.target, c.bytes);
            ::alarm(0);
            return passed;
        });
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::cout << (outcome.empty() ? "pass  " : "FAIL  ") << c.name << " (" << c.bytes.size() << " bytes, " << seconds
                  << " s)" << (outcome.empty() ? "" : ": " + outcome)
                  << (c.what.empty() ? "" : " [generated: " + c.what + "]") << "\n";
        if (!outcome.empty()) ++failures;
    }
    std::cout << "fuzz regressions: " << cases.size() - static_cast<std::size_t>(failures) << " of " << cases.size()
              << " pass\n";
    return failures ? 1 : 0;
}

int write_generated(const fs::path& folder) {
    for (const Reproducer& reproducer : generated_reproducers()) {
        const fs::path path = folder / reproducer.target / reproducer.name;
        fs::create_directories(path.parent_path());
        std::ofstream out(path, std::ios::binary);
        out.write(reinterpret_cast<const char*>(reproducer.bytes.data()), static_cast<std::streamsize>(reproducer.bytes.size()));
        std::cout << path.string() << "  (" << reproducer.what << ")\n";
    }
    return 0;
}

// COUNT mutations of a target's corpus as files (the Python replay feeds them to the module).
int write_mutations(const fs::path& corpus_root, const std::string& target_name, int count, const fs::path& folder) {
    const FuzzTarget* target = find_fuzz_target(target_name);
    if (!target) {
        std::cerr << "unknown target " << target_name << "\n";
        return 2;
    }
    std::vector<Bytes> seeds;
    for (const fs::path& file : files_in(corpus_root / target->name)) seeds.push_back(read_bytes(file));
    if (seeds.empty()) return 1;
    fs::create_directories(folder);
    MutationRandom random(20261122u ^ std::hash<std::string>{}(target->name));
    for (int m = 0; m < count; ++m) {
        std::size_t seed_index = 0;
        std::string how;
        const Bytes input = mutated_input(*target, seeds, random, seed_index, how);
        std::ofstream out(folder / (target->name + "-" + std::to_string(m) + "-" + how), std::ios::binary);
        out.write(reinterpret_cast<const char*>(input.data()), static_cast<std::streamsize>(input.size()));
    }
    return 0;
}

int run_files(const std::string& target_name, const std::vector<std::string>& files) {
    const FuzzTarget* target = find_fuzz_target(target_name);
    if (!target) {
        std::cerr << "unknown target " << target_name << "\n";
        return 2;
    }
    install_handlers();
    g_limit_allocations = true;
    bool passed = true;
    for (const std::string& file : files) {
        const Bytes input = read_bytes(file);
        set_current(input, target_name + ": " + file, file + ".failure");
        const auto start = std::chrono::steady_clock::now();
        if (!run_checked(*target, input)) passed = false;
        std::cerr << file << ": " << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() << " s\n";
    }
    return passed ? 0 : 1;
}

int usage() {
    std::cerr << "usage: flowvid_fuzz_replay corpus CORPUS_DIR MUTATIONS_PER_TARGET [TARGET...] [--crash-dir DIR]\n"
                 "       flowvid_fuzz_replay regressions REGRESSIONS_DIR [--crash-dir DIR]\n"
                 "       flowvid_fuzz_replay write-generated DIR\n"
                 "       flowvid_fuzz_replay mutate CORPUS_DIR TARGET COUNT DIR\n"
                 "       flowvid_fuzz_replay run TARGET FILE...\n";
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    std::vector<std::string> args(argv + 1, argv + argc);
    fs::path crash_dir = "fuzz-crashes";
    if (const auto it = std::find(args.begin(), args.end(), "--crash-dir"); it != args.end()) {
        if (it + 1 == args.end()) return usage();
        crash_dir = *(it + 1);
        args.erase(it, it + 2);
    }
    if (args.empty()) return usage();
    const std::string mode = args[0];
    if (mode == "corpus" && args.size() >= 3) {
        fs::create_directories(crash_dir);
        return replay_corpus(args[1], std::stoi(args[2]), std::vector<std::string>(args.begin() + 3, args.end()), crash_dir);
    }
    if (mode == "regressions" && args.size() == 2) {
        fs::create_directories(crash_dir);
        return replay_regressions(args[1], crash_dir);
    }
    if (mode == "write-generated" && args.size() == 2) return write_generated(args[1]);
    if (mode == "mutate" && args.size() == 5) return write_mutations(args[1], args[2], std::stoi(args[3]), args[4]);
    if (mode == "run" && args.size() >= 3) return run_files(args[1], std::vector<std::string>(args.begin() + 2, args.end()));
    return usage();
}
