// The head tool: builds the built-in head (protocols/head/) from the CC0
// MakeHuman assets (head_builder.h); scripts/make-head runs it.
//   avsi_make_head [--assets DIR] [--out DIR] [--variant male|female|dark-male|all]
// With --sheet OUT.png it instead renders the contact sheet of the committed
// default head (a quick look without building the avsi executable).
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "avsi/core/error.h"
#include "avsi/stimuli/contact_sheet.h"
#include "avsi/stimuli/head_builder.h"
#include "avsi/stimuli/image_io.h"

int main(int argc, char** argv) {
    using namespace avsi::stimuli;
    HeadBuildSettings settings;
    settings.assets_dir = std::filesystem::path(AVSI_SHARED_DIR) / "assets" / "makehuman";
    settings.out_dir = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "head";
    std::string variant = "all", sheet;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (i + 1 < argc && a == "--assets") settings.assets_dir = argv[++i];
        else if (i + 1 < argc && a == "--out") settings.out_dir = argv[++i];
        else if (i + 1 < argc && a == "--variant") variant = argv[++i];
        else if (i + 1 < argc && a == "--sheet") sheet = argv[++i];
        else {
            std::fprintf(stderr,
                         "usage: avsi_make_head [--assets DIR] [--out DIR] [--variant male|female|dark-male|all]\n"
                         "       avsi_make_head --sheet OUT.png\n");
            return 2;
        }
    }
    try {
        if (!sheet.empty()) {
            const auto head = load_default_head();
            write_png(sheet, render_contact_sheet(head, read_sheet_targets(default_sheet_targets())));
            return 0;
        }
        std::vector<HeadVariant> variants;
        if (variant == "all") variants = {HeadVariant::Male, HeadVariant::Female, HeadVariant::DarkMale};
        else variants = {head_variant_from_name(variant)};
        for (const auto v : variants) {
            settings.variant = v;
            build_head(settings);
            std::printf("wrote %s/%s.{obj,rig.json,png}\n", settings.out_dir.string().c_str(), head_variant_stem(v).c_str());
        }
    } catch (const avsi::UsageError& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
    return 0;
}
