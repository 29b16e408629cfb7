// Haskins IEEE rate database .mat recordings through matio (haskins_mat.h).
#include "avsi/learn/haskins_mat.h"

#include <matio.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"

namespace avsi::learn {

namespace {

// matio reports problems through a log function; the library must not print,
// so its messages are kept (per thread) for the error text.
thread_local std::string t_matio_message;

void matio_log(int /*level*/, char* message) {
    if (message) t_matio_message = message;
}

void install_matio_log() {
    static std::once_flag once;
    std::call_once(once, [] { Mat_LogInitFunc("avsi", matio_log); });
}

struct MatCloser {
    void operator()(mat_t* m) const { Mat_Close(m); }
};
struct VarFreer {
    void operator()(matvar_t* v) const { Mat_VarFree(v); }
};

std::size_t element_count(const matvar_t* v) {
    std::size_t n = 1;
    for (int d = 0; d < v->rank; ++d) n *= v->dims[d];
    return n;
}

// The values of a real numeric array (any class), column-major; nullopt otherwise.
std::optional<std::vector<double>> numbers(const matvar_t* v) {
    if (!v || v->isComplex || !v->data) return std::nullopt;
    const std::size_t n = element_count(v);
    std::vector<double> out(n);
    auto copy = [&](auto tag) {
        using T = decltype(tag);
        const T* p = static_cast<const T*>(v->data);
        for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<double>(p[i]);
    };
    switch (v->data_type) {
        case MAT_T_DOUBLE: copy(double{}); break;
        case MAT_T_SINGLE: copy(float{}); break;
        case MAT_T_INT8: copy(std::int8_t{}); break;
        case MAT_T_UINT8: copy(std::uint8_t{}); break;
        case MAT_T_INT16: copy(std::int16_t{}); break;
        case MAT_T_UINT16: copy(std::uint16_t{}); break;
        case MAT_T_INT32: copy(std::int32_t{}); break;
        case MAT_T_UINT32: copy(std::uint32_t{}); break;
        case MAT_T_INT64: copy(std::int64_t{}); break;
        case MAT_T_UINT64: copy(std::uint64_t{}); break;
        default: return std::nullopt;
    }
    switch (v->class_type) {
        case MAT_C_DOUBLE: case MAT_C_SINGLE: case MAT_C_INT8: case MAT_C_UINT8: case MAT_C_INT16:
        case MAT_C_UINT16: case MAT_C_INT32: case MAT_C_UINT32: case MAT_C_INT64: case MAT_C_UINT64:
            return out;
        default: return std::nullopt;
    }
}

// The text of a char array (one row; MATLAB stores UTF-16, ASCII here).
std::optional<std::string> text(const matvar_t* v) {
    if (!v || v->class_type != MAT_C_CHAR) return std::nullopt;
    const std::size_t n = element_count(v);
    std::string out;
    if (n == 0 || !v->data) return out;
    if (v->data_size == 1) {
        out.assign(static_cast<const char*>(v->data), n);
    } else if (v->data_size == 2) {
        const auto* p = static_cast<const std::uint16_t*>(v->data);
        for (std::size_t i = 0; i < n; ++i) out += p[i] < 0x80 ? static_cast<char>(p[i]) : '?';
    } else {
        return std::nullopt;
    }
    return trim(out);
}

class Reader {
public:
    explicit Reader(std::filesystem::path path) : m_path(std::move(path)), m_file(m_path.string()) {}

    HaskinsRecording read() {
        install_matio_log();
        t_matio_message.clear();
        std::unique_ptr<mat_t, MatCloser> mat(Mat_Open(m_file.c_str(), MAT_ACC_RDONLY));
        if (!mat)
            throw InputError(m_path, fmt::format("expected a MATLAB .mat file (version 5 or 7.3), could not open "
                                                 "it{}",
                                                 t_matio_message.empty() ? "" : ": " + t_matio_message));
        HaskinsRecording rec;
        rec.variable = m_path.stem().string();
        std::unique_ptr<matvar_t, VarFreer> var(Mat_VarRead(mat.get(), rec.variable.c_str()));
        if (!var) {
            // A file renamed after it was saved: its one struct array will do.
            Mat_Rewind(mat.get());
            std::vector<std::string> names;
            while (matvar_t* info = Mat_VarReadNextInfo(mat.get())) {
                if (info->class_type == MAT_C_STRUCT && info->name) names.emplace_back(info->name);
                Mat_VarFree(info);
            }
            if (names.size() != 1)
                throw InputError(m_file, 0, 0, rec.variable,
                                 fmt::format("expected a struct array named after the file (\"{}\"), got {} struct "
                                             "arrays{}",
                                             rec.variable, names.size(),
                                             t_matio_message.empty() ? "" : " (" + t_matio_message + ")"));
            log_info("{}: the struct array is named \"{}\", not after the file", m_file, names.front());
            rec.variable = names.front();
            var.reset(Mat_VarRead(mat.get(), rec.variable.c_str()));
            if (!var) throw InputError(m_file, 0, 0, rec.variable, "could not read the struct array");
        }
        if (var->class_type != MAT_C_STRUCT)
            throw InputError(m_file, 0, 0, rec.variable, "expected a struct array (one element per channel)");
        const std::size_t n = element_count(var.get());
        bool have_audio = false;
        std::size_t rows = 0;
        for (std::size_t i = 0; i < n; ++i) {
            const int line = static_cast<int>(i + 1);
            const std::optional<std::string> name = text(field(var.get(), "NAME", i, "", line));
            if (!name || name->empty()) fail(line, fmt::format("element {} NAME", i + 1), "expected a channel name (text)");
            const std::string where = fmt::format("element {} ({})", i + 1, *name);
            const auto rate = numbers(field(var.get(), "SRATE", i, where, line));
            if (!rate || rate->size() != 1 || !((*rate)[0] > 0.0) || !std::isfinite((*rate)[0]))
                fail(line, where + " SRATE", "expected a sample rate > 0 (one number)");
            matvar_t* signal = field(var.get(), "SIGNAL", i, where, line);
            if (ascii_lower(*name) == "audio") {
                have_audio = true;
                rec.audio_rate_hz = (*rate)[0];
                rec.audio_samples = element_count(signal);
                if (const auto sentence = text(Mat_VarGetStructFieldByName(var.get(), "SENTENCE", i)))
                    rec.sentence = *sentence;
                rec.words = segments(var.get(), "WORDS", i, where, line);
                rec.phones = segments(var.get(), "PHONES", i, where, line);
                continue;
            }
            // A sensor: SIGNAL N × 6 (x, y, z, then orientation).
            const auto values = numbers(signal);
            if (!values || signal->rank != 2 || signal->dims[1] < 3)
                fail(line, where + " SIGNAL",
                     fmt::format("expected N × 6 numbers (x, y, z in mm, then 3 orientation values), got {}",
                                 describe(signal)));
            if (rec.sensors.empty()) {
                rec.sensor_rate_hz = (*rate)[0];
                rows = signal->dims[0];
            } else if ((*rate)[0] != rec.sensor_rate_hz) {
                fail(line, where + " SRATE",
                     fmt::format("expected the rate of the sensors before ({} Hz), got {} Hz", rec.sensor_rate_hz,
                                 (*rate)[0]));
            } else if (signal->dims[0] != rows) {
                fail(line, where + " SIGNAL",
                     fmt::format("expected {} samples like the sensors before, got {}", rows, signal->dims[0]));
            }
            rec.sensors.push_back(*name);
            for (const char* axis : {"_x", "_y", "_z"}) rec.track.channels.push_back(*name + axis);
            m_columns.push_back(*values);
        }
        if (!have_audio) fail(0, "AUDIO", "expected an element named AUDIO (with the sentence, words and phones)");
        if (rec.sensors.empty()) fail(0, "SIGNAL", "expected sensor elements (TR TB TT UL LL ML JAW JAWL), got none");
        if (rows < 2) fail(0, "SIGNAL", fmt::format("expected at least 2 sensor samples, got {}", rows));
        // Frames: column-major N × 6 per sensor; a frame with every coordinate NaN is a dropout.
        rec.track.times_s.resize(rows);
        rec.track.present.resize(rows);
        rec.track.values.assign(rows, std::vector<float>(rec.track.channels.size()));
        for (std::size_t k = 0; k < rows; ++k) {
            rec.track.times_s[k] = static_cast<double>(k) / rec.sensor_rate_hz;
            bool any = false;
            for (std::size_t s = 0; s < m_columns.size(); ++s)
                for (std::size_t a = 0; a < 3; ++a) {
                    const double v = m_columns[s][a * rows + k];
                    rec.track.values[k][s * 3 + a] = static_cast<float>(v);
                    any = any || std::isfinite(v);
                }
            rec.track.present[k] = any;
        }
        return rec;
    }

private:
    [[noreturn]] void fail(int line, const std::string& field_name, const std::string& message) const {
        throw InputError(m_file, line, 0, field_name, message);
    }

    static std::string describe(const matvar_t* v) {
        if (!v) return "nothing";
        std::string dims;
        for (int d = 0; d < v->rank; ++d) dims += (d ? " × " : "") + std::to_string(v->dims[d]);
        return fmt::format("a {} array", dims);
    }

    matvar_t* field(matvar_t* var, const char* name, std::size_t i, const std::string& where, int line) const {
        matvar_t* f = Mat_VarGetStructFieldByName(var, name, i);
        if (!f) fail(line, (where.empty() ? fmt::format("element {}", i + 1) : where) + " " + name, "missing field");
        return f;
    }

    // A WORDS / PHONES struct array: LABEL and OFFS = [start end] in seconds.
    std::vector<Interval> segments(matvar_t* var, const char* name, std::size_t i, const std::string& where,
                                   int line) const {
        matvar_t* s = field(var, name, i, where, line);
        const std::string f = where + " " + name;
        if (s->class_type != MAT_C_STRUCT) fail(line, f, "expected a struct array of LABEL and OFFS");
        std::vector<Interval> out;
        const std::size_t n = element_count(s);
        for (std::size_t j = 0; j < n; ++j) {
            const auto label = text(Mat_VarGetStructFieldByName(s, "LABEL", j));
            const auto offs = numbers(Mat_VarGetStructFieldByName(s, "OFFS", j));
            if (!label) fail(line, fmt::format("{}({}).LABEL", f, j + 1), "expected a label (text)");
            if (!offs || offs->size() != 2 || !std::isfinite((*offs)[0]) || !std::isfinite((*offs)[1]) ||
                (*offs)[0] < 0.0 || (*offs)[1] < (*offs)[0])
                fail(line, fmt::format("{}({}).OFFS", f, j + 1),
                     fmt::format("expected [start end] in seconds with 0 <= start <= end, got {}",
                                 offs ? fmt::format("{}", fmt::join(*offs, " ")) : std::string("no numbers")));
            out.push_back({(*offs)[0], (*offs)[1], *label, static_cast<int>(j + 1)});
        }
        return out;
    }

    std::filesystem::path m_path;
    std::string m_file;
    std::vector<std::vector<double>> m_columns;  // per sensor: SIGNAL column-major
};

}  // namespace

HaskinsRecording read_haskins_mat(const std::filesystem::path& path) { return Reader(path).read(); }

}  // namespace avsi::learn
