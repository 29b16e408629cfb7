// `avsi fap2traj`: an MPEG-4 FAP v2.1 file (avsi's, Greta's, …) → an
// articulatory trajectory CSV by the least-squares inverse of the FAP mapping;
// FAP groups it cannot map and parameters outside their range are warned
// about (--clamp limits them). docs/fap.md.
#include <memory>

#include "avsi/synth/synthesis.h"
#include "command.h"

namespace avsi::cli {
namespace {

const bool registered_fap2traj = register_command({
    "fap2traj",
    "MPEG-4 FAP stream (.fap v2.1) to an articulatory trajectory CSV",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<synth::FapConversionSettings>();
        sub.add_option("input", o->in_path, "FAP file to read")->required()->capture_default_str();
        sub.add_option("--out", o->out_path, "Trajectory CSV to write")->required()->capture_default_str();
        sub.add_flag("--clamp", o->clamp,
                     "Limit decoded parameters to their documented range (without it they are kept and warned about)");
        return [o] {
            synth::run_fap_to_trajectory(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
