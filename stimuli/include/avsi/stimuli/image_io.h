// Reading and writing frames as image files (PNG) through OpenImageIO.
#pragma once

#include <filesystem>

#include "avsi/stimuli/renderer.h"

namespace avsi::stimuli {

// Writes an 8-bit RGB PNG atomically (parent folders created).
void write_png(const std::filesystem::path& path, const Image& image);
// Reads any image OIIO reads as 8-bit RGB (grey is replicated). Throws InputError.
Image read_image(const std::filesystem::path& path);

// Reads any image OIIO reads as 8-bit RGBA (alpha 255 when it has none). Throws InputError.
ImageRgba read_image_rgba(const std::filesystem::path& path);
// Writes an 8-bit RGBA PNG atomically (parent folders created).
void write_png_rgba(const std::filesystem::path& path, const ImageRgba& image);

}  // namespace avsi::stimuli
