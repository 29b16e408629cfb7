// File helpers: whole-file reads, and writes that never leave a half-written
// file in place of a good one (write to a temporary beside it, fsync, rename).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace avsi {

// Reads a whole file as bytes. Throws InputError naming the file.
std::string read_text_file(const std::filesystem::path& path);

// Writes `content` to `path` atomically (creating parent folders).
void write_text_file(const std::filesystem::path& path, std::string_view content);

// A temporary file beside `target` that replaces it on commit(), and is
// removed if destroyed without commit().
class AtomicFile {
public:
    explicit AtomicFile(std::filesystem::path target);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    const std::filesystem::path& temp_path() const { return m_temp; }
    const std::filesystem::path& target() const { return m_target; }
    // fsyncs the temporary and renames it over the target.
    void commit();

private:
    std::filesystem::path m_target;
    std::filesystem::path m_temp;
    bool m_committed = false;
};

// SHA-256 of bytes and of a file's contents, as lower-case hex.
std::string sha256_hex(std::string_view bytes);
std::string sha256_file(const std::filesystem::path& path);

}  // namespace avsi
