// ZIP archives through libzip, for the JATOS study archive (.jzip) the web
// export writes and the JATOS results archive (.jrzip/.zip) the import reads.
#pragma once

#include <filesystem>
#include <list>
#include <string>
#include <vector>

struct zip;

namespace avsi::experiment::detail {

// Writes an archive at a temporary path beside `target`; commit() closes it
// and renames it into place (a failed export leaves no half archive).
class ZipWriter {
public:
    explicit ZipWriter(std::filesystem::path target);
    ~ZipWriter();
    ZipWriter(const ZipWriter&) = delete;
    ZipWriter& operator=(const ZipWriter&) = delete;
    // A folder entry ("name/").
    void add_folder(const std::string& name);
    // A file's contents; `compress` false stores it (media are compressed already).
    void add_file(const std::string& name, const std::filesystem::path& source, bool compress);
    void add_text(const std::string& name, std::string text);
    void commit();

private:
    std::filesystem::path m_target;
    std::filesystem::path m_temp;
    ::zip* m_zip = nullptr;
    std::list<std::string> m_buffers;  // kept alive until the archive is closed
};

// Reads an archive's entries.
class ZipReader {
public:
    // Throws InputError naming the file if it is not a ZIP archive.
    explicit ZipReader(const std::filesystem::path& path);
    ~ZipReader();
    ZipReader(const ZipReader&) = delete;
    ZipReader& operator=(const ZipReader&) = delete;
    // Entry names in archive order.
    const std::vector<std::string>& names() const { return m_names; }
    // An entry's bytes; refuses entries over `max_bytes` (InputError).
    std::string read(const std::string& name, std::size_t max_bytes = std::size_t{1} << 30) const;

private:
    std::filesystem::path m_path;
    ::zip* m_zip = nullptr;
    std::vector<std::string> m_names;
};

}  // namespace avsi::experiment::detail
