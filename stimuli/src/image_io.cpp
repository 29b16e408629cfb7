// PNG frames through OpenImageIO.
#include "avsi/stimuli/image_io.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::stimuli {

namespace {

void write_png_channels(const std::filesystem::path& path, int width, int height, int channels, const std::uint8_t* data) {
    if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
    AtomicFile file(path);
    // OIIO picks the format by extension; the temporary keeps ".png" last.
    const std::filesystem::path temp = file.temp_path().string() + ".png";
    auto out = OIIO::ImageOutput::create("png");
    if (!out) throw InputError(path, "cannot create a PNG writer: " + OIIO::geterror());
    OIIO::ImageSpec spec(width, height, channels, OIIO::TypeDesc::UINT8);
    if (!out->open(temp.string(), spec) || !out->write_image(OIIO::TypeDesc::UINT8, data) || !out->close())
        throw InputError(path, "cannot write PNG: " + out->geterror());
    std::filesystem::rename(temp, file.temp_path());
    file.commit();
}

}  // namespace

void write_png_rgba(const std::filesystem::path& path, const ImageRgba& image) {
    write_png_channels(path, image.width, image.height, 4, image.rgba.data());
}

ImageRgba read_image_rgba(const std::filesystem::path& path) {
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) throw InputError(path, "cannot read image: " + OIIO::geterror());
    const auto& spec = in->spec();
    // A header's size is checked before its pixels are allocated (a texture
    // is at most 16384 pixels on a side, 1 to 4 channels).
    if (spec.width <= 0 || spec.height <= 0 || spec.width > 16384 || spec.height > 16384 || spec.nchannels < 1 || spec.nchannels > 4)
        throw InputError(path.string(), 0, 0, "size",
                         fmt::format("expected an image of at most 16384 × 16384 pixels with 1 to 4 channels, got {} × {} × {}",
                                     spec.width, spec.height, spec.nchannels));
    const auto channels = static_cast<std::size_t>(spec.nchannels);
    std::vector<std::uint8_t> pixels(static_cast<std::size_t>(spec.width) * static_cast<std::size_t>(spec.height) * channels);
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, pixels.data()))
        throw InputError(path, "cannot read image: " + in->geterror());
    ImageRgba image;
    image.width = spec.width;
    image.height = spec.height;
    image.rgba.resize(pixels.size() / channels * 4);
    for (std::size_t i = 0; i < image.rgba.size() / 4; ++i) {
        for (std::size_t c = 0; c < 3; ++c) image.rgba[4 * i + c] = pixels[i * channels + std::min(c, channels > 2 ? c : 0)];
        image.rgba[4 * i + 3] = channels == 4 ? pixels[i * channels + 3] : channels == 2 ? pixels[i * channels + 1] : 255;
    }
    return image;
}

void write_png(const std::filesystem::path& path, const Image& image) {
    write_png_channels(path, image.width, image.height, 3, image.rgb.data());
}

Image read_image(const std::filesystem::path& path) {
    auto in = OIIO::ImageInput::open(path.string());
    if (!in) throw InputError(path, "cannot read image: " + OIIO::geterror());
    const auto& spec = in->spec();
    Image image;
    image.width = spec.width;
    image.height = spec.height;
    std::vector<std::uint8_t> pixels(static_cast<std::size_t>(spec.width) * static_cast<std::size_t>(spec.height) *
                                     static_cast<std::size_t>(spec.nchannels));
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, pixels.data()))
        throw InputError(path, "cannot read image: " + in->geterror());
    image.rgb.resize(static_cast<std::size_t>(spec.width) * static_cast<std::size_t>(spec.height) * 3);
    for (std::size_t i = 0; i < image.rgb.size() / 3; ++i)
        for (std::size_t c = 0; c < 3; ++c)
            image.rgb[3 * i + c] =
                pixels[i * static_cast<std::size_t>(spec.nchannels) +
                       std::min<std::size_t>(c, static_cast<std::size_t>(spec.nchannels) - 1)];
    return image;
}

}  // namespace avsi::stimuli
