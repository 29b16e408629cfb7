#include "avsi/core/files.h"

#include <fcntl.h>
#include <unistd.h>

#include <openssl/evp.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"

namespace avsi {

namespace fs = std::filesystem;

std::string read_text_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        if (!fs::exists(path)) throw InputError(path, "cannot open: no such file");
        throw InputError(path, fmt::format("cannot open: {}", std::strerror(errno)));
    }
    std::ostringstream buffer;
    buffer << in.rdbuf();
    return buffer.str();
}

namespace {
fs::path temp_name_for(const fs::path& target) {
    static std::atomic<unsigned> counter{0};
    return target.parent_path() /
           fmt::format(".{}.tmp{}-{}", target.filename().string(), ::getpid(), counter++);
}

// Flushes `path` (a file or a folder) to disk: 0, or the errno of what
// failed. EINVAL counts as done: the file system cannot sync it (some FUSE
// and network mounts), and there is nothing more to wait for.
int fsync_path(const fs::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return errno;
    const int error = ::fsync(fd) == 0 ? 0 : errno;
    ::close(fd);
    return error == EINVAL ? 0 : error;
}
}  // namespace

AtomicFile::AtomicFile(fs::path target) : m_target(std::move(target)) {
    if (m_target.has_parent_path()) {
        std::error_code ec;
        fs::create_directories(m_target.parent_path(), ec);
        if (ec) throw InputError(m_target, fmt::format("cannot create folder: {}", ec.message()));
    }
    m_temp = temp_name_for(m_target);
}

AtomicFile::~AtomicFile() {
    if (!m_committed) {
        std::error_code ec;
        fs::remove(m_temp, ec);
    }
}

void AtomicFile::commit() {
    // A write the disk refused (EIO, or no space for what was delayed)
    // shows only here: then the file stays as it was, and the temporary goes.
    if (const int error = fsync_path(m_temp))
        throw InputError(m_target, fmt::format("cannot write: {} while flushing it to disk; the file was not "
                                               "replaced",
                                               std::strerror(error)));
    std::error_code ec;
    fs::rename(m_temp, m_target, ec);
    if (ec) throw InputError(m_target, fmt::format("cannot write: {}", ec.message()));
    m_committed = true;
    if (m_target.has_parent_path())
        if (const int error = fsync_path(m_target.parent_path()))
            log_warning("{}: written, but its folder could not be flushed to disk ({}): a crash now could "
                        "lose the new name",
                        m_target.string(), std::strerror(error));
}

void write_text_file(const fs::path& path, std::string_view content) {
    AtomicFile file(path);
    {
        std::ofstream out(file.temp_path(), std::ios::binary);
        if (!out) throw InputError(path, fmt::format("cannot write: {}", std::strerror(errno)));
        out.write(content.data(), static_cast<std::streamsize>(content.size()));
        out.flush();
        if (!out) throw InputError(path, "cannot write: short write (disk full?)");
    }
    file.commit();
}

namespace {
std::string to_hex(const unsigned char* data, unsigned int size) {
    static constexpr char digits[] = "0123456789abcdef";
    std::string out(size * 2, '0');
    for (unsigned int i = 0; i < size; ++i) {
        out[2 * i] = digits[data[i] >> 4];
        out[2 * i + 1] = digits[data[i] & 15];
    }
    return out;
}

struct DigestContext {
    EVP_MD_CTX* ctx = EVP_MD_CTX_new();
    DigestContext() {
        AVSI_ASSERT(ctx != nullptr);
        EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
    }
    ~DigestContext() { EVP_MD_CTX_free(ctx); }
    void update(const void* data, std::size_t size) { EVP_DigestUpdate(ctx, data, size); }
    std::string hex() {
        std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
        unsigned int size = 0;
        EVP_DigestFinal_ex(ctx, digest.data(), &size);
        return to_hex(digest.data(), size);
    }
};
}  // namespace

std::string sha256_hex(std::string_view bytes) {
    DigestContext d;
    d.update(bytes.data(), bytes.size());
    return d.hex();
}

std::string sha256_file(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "cannot open for hashing: no such file or not readable");
    DigestContext d;
    std::array<char, 1 << 16> buffer{};
    while (in) {
        in.read(buffer.data(), buffer.size());
        d.update(buffer.data(), static_cast<std::size_t>(in.gcount()));
    }
    return d.hex();
}

}  // namespace avsi
