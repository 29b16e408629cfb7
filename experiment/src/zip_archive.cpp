// ZIP reading and writing through libzip (see zip_archive.h).
#include "zip_archive.h"

#include <zip.h>

#include <fmt/format.h>

#include "avsi/core/error.h"

namespace avsi::experiment::detail {

namespace fs = std::filesystem;

ZipWriter::ZipWriter(fs::path target) : m_target(std::move(target)) {
    m_temp = m_target;
    m_temp += ".partial";
    if (m_target.has_parent_path()) fs::create_directories(m_target.parent_path());
    int error = 0;
    m_zip = zip_open(m_temp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
    if (!m_zip) {
        zip_error_t e;
        zip_error_init_with_code(&e, error);
        const std::string message = zip_error_strerror(&e);
        zip_error_fini(&e);
        throw InputError(m_target, "cannot write the archive: " + message);
    }
}

ZipWriter::~ZipWriter() {
    if (m_zip) {
        zip_discard(m_zip);
        std::error_code ignored;
        fs::remove(m_temp, ignored);
    }
}

void ZipWriter::add_folder(const std::string& name) {
    if (zip_dir_add(m_zip, name.c_str(), ZIP_FL_ENC_UTF_8) < 0)
        throw InputError(m_target, fmt::format("cannot add {}: {}", name, zip_strerror(m_zip)));
}

void ZipWriter::add_file(const std::string& name, const fs::path& source, bool compress) {
    zip_source_t* src = zip_source_file(m_zip, source.c_str(), 0, -1);
    if (!src) throw InputError(source, fmt::format("cannot read for the archive: {}", zip_strerror(m_zip)));
    const zip_int64_t index = zip_file_add(m_zip, name.c_str(), src, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE);
    if (index < 0) {
        zip_source_free(src);
        throw InputError(m_target, fmt::format("cannot add {}: {}", name, zip_strerror(m_zip)));
    }
    if (!compress) zip_set_file_compression(m_zip, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0);
}

void ZipWriter::add_text(const std::string& name, std::string text) {
    const std::string& kept = m_buffers.emplace_back(std::move(text));
    zip_source_t* src = zip_source_buffer(m_zip, kept.data(), kept.size(), 0);
    if (!src || zip_file_add(m_zip, name.c_str(), src, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE) < 0) {
        if (src) zip_source_free(src);
        throw InputError(m_target, fmt::format("cannot add {}: {}", name, zip_strerror(m_zip)));
    }
}

void ZipWriter::commit() {
    if (zip_close(m_zip) < 0) {
        const std::string message = zip_strerror(m_zip);
        zip_discard(m_zip);
        m_zip = nullptr;
        throw InputError(m_target, "cannot write the archive: " + message);
    }
    m_zip = nullptr;
    fs::rename(m_temp, m_target);
}

ZipReader::ZipReader(const fs::path& path) : m_path(path) {
    int error = 0;
    m_zip = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
    if (!m_zip) {
        zip_error_t e;
        zip_error_init_with_code(&e, error);
        const std::string message = zip_error_strerror(&e);
        zip_error_fini(&e);
        throw InputError(path, "not a readable ZIP archive (" + message + "): truncated or damaged?");
    }
    const zip_int64_t n = zip_get_num_entries(m_zip, 0);
    for (zip_int64_t i = 0; i < n; ++i) {
        const char* name = zip_get_name(m_zip, static_cast<zip_uint64_t>(i), ZIP_FL_ENC_GUESS);
        m_names.emplace_back(name ? name : "");
    }
}

ZipReader::~ZipReader() {
    if (m_zip) zip_close(m_zip);
}

std::string ZipReader::read(const std::string& name, std::size_t max_bytes) const {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat(m_zip, name.c_str(), 0, &st) < 0 || !(st.valid & ZIP_STAT_SIZE))
        throw InputError(m_path, fmt::format("cannot read entry {}: {}", name, zip_strerror(m_zip)));
    if (st.size > max_bytes)
        throw InputError(m_path, fmt::format("entry {} is {} bytes, more than the {} bytes accepted", name, st.size,
                                             max_bytes));
    zip_file_t* file = zip_fopen(m_zip, name.c_str(), 0);
    if (!file) throw InputError(m_path, fmt::format("cannot open entry {}: {}", name, zip_strerror(m_zip)));
    std::string bytes(static_cast<std::size_t>(st.size), '\0');
    const zip_int64_t got = zip_fread(file, bytes.data(), bytes.size());
    zip_fclose(file);
    if (got < 0 || static_cast<zip_uint64_t>(got) != st.size)
        throw InputError(m_path, fmt::format("entry {} is damaged (read {} of {} bytes)", name, got, st.size));
    return bytes;
}

}  // namespace avsi::experiment::detail
