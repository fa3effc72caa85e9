#pragma once
// Atomic writes: every flowvid writer produces its file through these helpers,
// so a crash, a full disk or an exception half-way never leaves a truncated
// preset or bank in place of the previous good one.

#include <functional>
#include <iosfwd>
#include <string>

namespace flowvid::formats {

// Calls write_body with a stream to a temporary file beside `path`, flushes and
// syncs it, then renames it over `path`. If write_body throws or the stream
// fails, the temporary file is removed, `path` is untouched, and the error is
// rethrown (stream failures as flowvid::IoError naming `path`).
void write_file_atomically(const std::string& path, const std::function<void(std::ostream&)>& write_body);

// The same for writers that need a file name rather than a stream (OpenEXR,
// tinygltf): write_to writes the whole file at the temporary path it is given.
void write_path_atomically(const std::string& path, const std::function<void(const std::string& temp_path)>& write_to);

// For writers that stream into a file over a long time (a video encoder):
// write to temp_path(), then commit() renames it over the target. Destroyed
// without commit() (an error, Ctrl-C), it removes the temporary file and
// leaves the target as it was. The temporary name keeps the target's
// extension, since encoders pick the container from it.
class PendingFile {
public:
    explicit PendingFile(const std::string& path);
    ~PendingFile();
    PendingFile(const PendingFile&) = delete;
    PendingFile& operator=(const PendingFile&) = delete;
    const std::string& temp_path() const { return m_temp_path; }
    const std::string& path() const { return m_path; }
    void commit();   // throws IoError naming the target when the rename fails
    void discard();  // removes the temporary file now

private:
    std::string m_path;
    std::string m_temp_path;
    bool m_done = false;
};

// Reads a whole file; throws flowvid::IoError naming the file when it cannot.
// Creates the folder a file will be written into, when missing, so that a
// typo fails at once rather than after long work. Throws IoError naming
// `file_path` when it cannot.
void create_parent_folder(const std::string& file_path);

std::string read_text_file(const std::string& path);

}  // namespace flowvid::formats
