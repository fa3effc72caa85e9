#include "flowvid/formats/atomic_file.hpp"

#include "flowvid/error.hpp"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace flowvid::formats {
namespace fs = std::filesystem;

namespace {

// ".name.tmp-PID-N" beside `path`; with `keep_extension`, ".stem.tmp-PID-N.ext"
// (encoders pick the container from the extension).
std::string temporary_sibling(const std::string& path, bool keep_extension = false) {
    static std::atomic<unsigned> counter{0};
    const fs::path target(path);
    const std::string unique = ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter.fetch_add(1));
    const std::string name = keep_extension ? "." + target.stem().string() + unique + target.extension().string()
                                            : "." + target.filename().string() + unique;
    return (target.parent_path() / name).string();
}

// fsync so that the rename never publishes a file whose data is not on disk.
void sync_file(const std::string& path) {
    int fd = ::open(path.c_str(), O_RDONLY);
    if (fd < 0) return;
    ::fsync(fd);
    ::close(fd);
}

void publish(const std::string& temp_path, const std::string& path) {
    sync_file(temp_path);
    std::error_code ec;
    fs::rename(temp_path, path, ec);
    if (ec) {
        fs::remove(temp_path, ec);
        throw IoError(path, "", "cannot replace the file: " + ec.message(),
                      "check that the folder is writable and on the same file system");
    }
}

}  // namespace

void write_path_atomically(const std::string& path, const std::function<void(const std::string&)>& write_to) {
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty() && !fs::is_directory(parent))
        throw IoError(path, "", "the folder does not exist", "create " + parent.string() + " first");
    const std::string temp_path = temporary_sibling(path);
    try {
        write_to(temp_path);
    } catch (...) {
        std::error_code ec;
        fs::remove(temp_path, ec);
        throw;
    }
    if (!fs::exists(temp_path))
        throw IoError(path, "", "the writer produced no file", "report this as a flowvid bug");
    publish(temp_path, path);
}

void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& write_body) {
    write_path_atomically(path, [&](const std::string& temp_path) {
        std::ofstream out(temp_path, std::ios::binary | std::ios::trunc);
        if (!out) throw IoError(path, "", std::string("cannot create a temporary file: ") + std::strerror(errno),
                                "check that the folder is writable");
        write_body(out);
        out.flush();
        if (!out) throw IoError(path, "", "writing failed (disk full?)", "free disk space and write again");
        out.close();
        if (!out) throw IoError(path, "", "closing the file failed", "free disk space and write again");
    });
}

PendingFile::PendingFile(const std::string& path) : m_path(path) {
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty() && !fs::is_directory(parent))
        throw IoError(path, "", "the folder does not exist", "create " + parent.string() + " first");
    m_temp_path = temporary_sibling(path, /*keep_extension=*/true);
}

PendingFile::~PendingFile() { discard(); }

void PendingFile::commit() {
    if (m_done) return;
    m_done = true;
    if (!fs::exists(m_temp_path))
        throw IoError(m_path, "", "the writer produced no file", "report this as a flowvid bug");
    publish(m_temp_path, m_path);
}

void PendingFile::discard() {
    if (m_done) return;
    m_done = true;
    std::error_code ec;
    fs::remove(m_temp_path, ec);
}

void create_parent_folder(const std::string& file_path) {
    const fs::path folder = fs::path(file_path).parent_path();
    if (folder.empty()) return;
    std::error_code error;
    fs::create_directories(folder, error);
    if (error || !fs::is_directory(folder))
        throw IoError(file_path, "", "cannot create the folder " + folder.string() + ": " + error.message(),
                      "choose a writable location");
}

std::string read_text_file(const std::string& path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError(path, "", "no such file", "check the path");
    if (fs::is_directory(path, ec)) throw IoError(path, "", "is a folder, not a file", "name a file inside it");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path, "", std::string("cannot open: ") + std::strerror(errno), "check permissions");
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad()) throw IoError(path, "", "read error", "check the file system");
    return text.str();
}

}  // namespace flowvid::formats
