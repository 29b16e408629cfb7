// Writes the built-in head: avsi_make_head OUT.obj OUT.rig.json
// (scripts/make-head runs it into protocols/head/). With --sheet OUT.png it
// instead renders the default contact sheet of the committed head (a quick
// look while tuning the generator, without building the avsi executable).
#include <cstdio>
#include <exception>
#include <string>

#include "avsi/stimuli/contact_sheet.h"
#include "avsi/stimuli/head_generator.h"
#include "avsi/stimuli/image_io.h"

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: avsi_make_head OUT.obj OUT.rig.json | avsi_make_head --sheet OUT.png\n");
        return 2;
    }
    try {
        if (std::string(argv[1]) == "--sheet") {
            const auto head = avsi::stimuli::load_default_head();
            const auto entries = avsi::stimuli::read_sheet_targets(avsi::stimuli::default_sheet_targets());
            avsi::stimuli::write_png(argv[2], avsi::stimuli::render_contact_sheet(head, entries));
        } else {
            avsi::stimuli::generate_head(argv[1], argv[2]);
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
    return 0;
}
