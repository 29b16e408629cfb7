// Contact sheet rendering; tiles pasted with OpenImageIO, labels drawn with cairo.
#include "avsi/stimuli/contact_sheet.h"

#include "avsi/stimuli/animation.h"

#include <cairo.h>

#include <cstring>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/log.h"

namespace avsi::stimuli {

std::filesystem::path default_sheet_targets() {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "head" / "contact_sheet_targets.csv";
}

std::vector<SheetEntry> read_sheet_targets(const std::filesystem::path& path) {
    const CsvTable table = read_csv(path);
    const std::size_t label_col = table.require_column("label");
    const std::size_t phone_col = table.require_column("phone");
    DiagnosticList problems;
    std::vector<std::pair<std::size_t, std::size_t>> columns;  // csv column, parameter
    std::vector<std::string> known{"label", "phone"};
    for (const auto& info : synth::params()) known.emplace_back(info.name);
    for (std::size_t c = 0; c < table.header.size(); ++c) {
        const auto& name = table.header[c];
        if (name == "label" || name == "phone") continue;
        const auto p = synth::param_from_name(name);
        if (!p) {
            const auto hint = closest_match(name, known);
            problems.add(path.string(), 1, 0, "header",
                         "unknown column \"" + name + "\"" + (hint.empty() ? "" : " (did you mean \"" + hint + "\"?)"));
            continue;
        }
        columns.emplace_back(c, synth::index(*p));
    }
    std::vector<SheetEntry> entries;
    for (const auto& row : table.rows) {
        SheetEntry e;
        e.label = row.fields.at(label_col);
        e.phone = row.fields.at(phone_col);
        for (const auto& [c, p] : columns) {
            const auto& text = row.fields.at(c);
            if (text.empty()) continue;
            const auto v = parse_double(text);
            const auto& info = synth::params()[p];
            if (!v || *v < info.min || *v > info.max) {
                problems.add(path.string(), row.line, 0, std::string(info.name),
                             "expected a number in [" + std::to_string(info.min) + ", " + std::to_string(info.max) +
                                 "], got \"" + text + "\"");
                continue;
            }
            e.pose.params[p] = *v;
        }
        // The tongue tip as the animation's rule layer raises it (animation.h).
        PhoneSequence one{{e.phone, 0.0, 1.0, false}};
        e.pose.tongue_tip = tongue_tip_track(one, 1, 2.0)[0];
        entries.push_back(std::move(e));
    }
    problems.throw_if_any();
    if (entries.empty()) throw InputError(path, "no targets in the file");
    return entries;
}

namespace {

// DejaVu Sans has the IPA glyphs (θ ʃ ɑ) (Debian: fonts-dejavu-core, in
// scripts/install-deps); cairo finds it through fontconfig.
void check_label_font() {
    for (const char* path : {"/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
                             "/usr/share/fonts/TTF/DejaVuSans.ttf", "/usr/share/fonts/dejavu/DejaVuSans.ttf"})
        if (std::filesystem::exists(path)) return;
    log_warning("contact sheet: DejaVu Sans not found (install fonts-dejavu-core); IPA labels may show as boxes");
}

// A label strip: `text` (UTF-8) in white on `background`, drawn with cairo
// (OpenImageIO's render_text shows non-Latin-1 characters as boxes).
void paste_label(OIIO::ImageBuf& sheet, int x0, int y0, int width, int height, const std::string& text,
                 const float (&background)[3]) {
    cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
    cairo_t* cr = cairo_create(surface);
    cairo_set_source_rgb(cr, background[0], background[1], background[2]);
    cairo_paint(cr);
    cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(cr, 22.0);
    cairo_set_source_rgb(cr, 1.0, 1.0, 1.0);
    cairo_move_to(cr, 10.0, 25.0);
    cairo_show_text(cr, text.c_str());
    cairo_surface_flush(surface);
    const unsigned char* data = cairo_image_surface_get_data(surface);
    const int stride = cairo_image_surface_get_stride(surface);
    std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            std::uint32_t px = 0;  // native-endian 0xXXRRGGBB
            std::memcpy(&px, data + static_cast<std::size_t>(y) * static_cast<std::size_t>(stride) + 4 * static_cast<std::size_t>(x), 4);
            std::uint8_t* dst = rgb.data() + 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x));
            dst[0] = static_cast<std::uint8_t>((px >> 16) & 0xff);
            dst[1] = static_cast<std::uint8_t>((px >> 8) & 0xff);
            dst[2] = static_cast<std::uint8_t>(px & 0xff);
        }
    cairo_destroy(cr);
    cairo_surface_destroy(surface);
    OIIO::ImageBuf strip(OIIO::ImageSpec(width, height, 3, OIIO::TypeDesc::UINT8), rgb.data());
    OIIO::ImageBufAlgo::paste(sheet, x0, y0, 0, 0, strip);
}

}  // namespace

Image render_contact_sheet(const Head& head, const std::vector<SheetEntry>& entries,
                           const ContactSheetSettings& settings) {
    RenderSettings rs;
    rs.width = settings.tile_width;
    rs.height = settings.tile_height;
    rs.framing_mm = settings.framing_mm;
    rs.camera = settings.camera;
    // Centred a little above the mouth, on the head's vertical axis, so each
    // tile shows the eyes, the whole chin and some neck.
    const glm::vec3 head_center = head.landmarks.head_center;
    rs.target = glm::vec3(head_center.x, head.landmarks.mouth_middle.y + 0.1f * settings.framing_mm, head_center.z);
    OffscreenRenderer renderer(head, rs);
    const int cols = std::max(1, std::min(settings.columns, static_cast<int>(entries.size())));
    const int rows = (static_cast<int>(entries.size()) + cols - 1) / cols;
    const int label_h = 34;
    const int tw = settings.tile_width, th = settings.tile_height + label_h;
    OIIO::ImageBuf sheet(OIIO::ImageSpec(cols * tw, rows * th, 3, OIIO::TypeDesc::UINT8));
    const float background[3] = {0.12f, 0.12f, 0.14f};
    OIIO::ImageBufAlgo::fill(sheet, background);
    check_label_font();
    Image tile;
    for (std::size_t i = 0; i < entries.size(); ++i) {
        renderer.render(entries[i].pose, tile);
        const int x0 = static_cast<int>(i % static_cast<std::size_t>(cols)) * tw;
        const int y0 = static_cast<int>(i / static_cast<std::size_t>(cols)) * th;
        OIIO::ImageBuf buf(OIIO::ImageSpec(tile.width, tile.height, 3, OIIO::TypeDesc::UINT8), tile.rgb.data());
        OIIO::ImageBufAlgo::paste(sheet, x0, y0 + label_h, 0, 0, buf);
        paste_label(sheet, x0, y0, tw, label_h, entries[i].label + "  " + entries[i].phone, background);
    }
    Image out;
    out.width = cols * tw;
    out.height = rows * th;
    out.rgb.resize(static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height) * 3);
    sheet.get_pixels(OIIO::ROI::All(), OIIO::TypeDesc::UINT8, out.rgb.data());
    return out;
}

}  // namespace avsi::stimuli
