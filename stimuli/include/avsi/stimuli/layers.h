// Layered animation (the Charisma paper, §3 "Rendering Manager", eq. 1–4):
// an animation is a stack of layers, each a track over the frames of a
// stimulus that sets some of the head's channels (the 10 articulatory
// parameters, blink, tongue tip, gaze, brows, cheeks; head.h) and optionally
// the head's rotation (a quaternion). Channels belong to the MPEG-4
// feature-point groups (ISO/IEC 14496-2 Annex C): jaw and inner lips, eyes,
// eyebrows, cheeks, tongue, head rotation, outer lips, nose, ears.
//
// Two sets of layers, as in the paper: dynamic modules (S_Mod: speech from
// the control model, blinks, gaze, idle head motion, expressions) and
// feature-point-group layers played from FAP or quaternion streams in
// direct mode (S_FPg). Blending, per channel and frame, over the layers that
// set the channel in that frame (docs/animation-layers.md):
//   - each layer has a weight (default 1) and optional weights per group;
//   - by default the modules override the stream layers completely (a
//     stream layer's default weight is 0 where a module sets the channel);
//   - value = Σ w_l·v_l / max(1, Σ w_l): LERP between the layers (two modules
//     at their default weights blend at 0.5 each) and, when the weights sum
//     to less than 1, toward the rest pose (a lone layer at 0.4 shows 40 %);
//   - the head rotation likewise with SLERP (a running weighted SLERP from
//     the identity);
//   - the speech layer owns the mouth groups (jaw and inner lips, outer
//     lips, tongue) unless LayerSettings::speech_owns_mouth is false: there
//     the speech layer's values pass through untouched, so no layer can undo
//     a bilabial closure (the closure hold, the lip contact).
//
// Usage (the one call the builder, `avsi render` and `avsi play` make):
//   const auto settings = parse_layer_settings(protocol.conditions[i].layers, protocol_dir, problems);
//   Animation a = animate(head, trajectory, &phones, settings);   // a.poses[k] for frame k
//   renderer.render(a.poses[k], image);                          // head rotation included
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/gtc/quaternion.hpp>

#include "avsi/core/config.h"
#include "avsi/core/phones.h"
#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/head.h"
#include "avsi/synth/fap.h"
#include "avsi/synth/trajectory.h"

namespace avsi::stimuli {

// The MPEG-4 feature-point groups (FAPs 3–68; 1 and 2 are the high-level
// viseme and expression FAPs, which avsi does not play).
enum class FeatureGroup { Jaw, Eyes, Eyebrows, Cheeks, Tongue, Head, OuterLips, Nose, Ears };
inline constexpr std::size_t feature_group_count = 9;

// "jaw", "eyes", "eyebrows", "cheeks", "tongue", "head", "outer_lips", "nose", "ears".
std::string_view feature_group_name(FeatureGroup group);
std::optional<FeatureGroup> feature_group_from_name(std::string_view name);
// The group of a FAP (3…68).
FeatureGroup fap_feature_group(int fap);
// The group of a rig channel: jaw_rotation, jaw_thrust, jaw_shift → Jaw; the
// lip parameters → OuterLips; blink and gaze → Eyes; brows → Eyebrows;
// cheek_raise → Cheeks; tongue_tip → Tongue.
FeatureGroup channel_group(std::size_t channel);
// Jaw, OuterLips and Tongue: the groups the speech layer owns by default.
bool is_mouth_group(FeatureGroup group);

// Which set a layer is in (the paper's S_Mod and S_FPg).
enum class LayerSet { Module, Stream };

// One frame of one layer: the channels it sets and, optionally, the head's rotation.
struct LayerFrame {
    std::array<double, channel_count> values{};
    std::array<bool, channel_count> set{};
    bool sets_rotation = false;
    glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};

    void set_channel(std::size_t c, double v) { values[c] = v, set[c] = true; }
    void set_rotation(const glm::quat& q) { rotation = q, sets_rotation = true; }
};

// A layer: a name for messages and the manifest, its set, its weights and
// one frame per output frame.
struct Layer {
    std::string name;
    LayerSet set = LayerSet::Module;
    bool is_speech = false;
    // The layer's weight; nullopt: the default (1, or 0 for a stream layer
    // where a module sets the channel).
    std::optional<double> weight;
    // Per group, overriding `weight` for the group's channels.
    std::array<std::optional<double>, feature_group_count> group_weights{};
    std::vector<LayerFrame> frames;
};

// The blend of a stack at frame k (see the file comment). `speech_owns_mouth`:
// the mouth groups take the speech layer's values alone.
Pose blend_frame(const std::vector<Layer>& layers, std::size_t k, bool speech_owns_mouth = true);

// ---- The layers -----------------------------------------------------------

// The control model's trajectory (10 parameters) and, with phones, the
// tongue tip (tongue_tip_track).
Layer speech_layer(const synth::Trajectory& trajectory, const PhoneSequence* phones);

// Blinks (blink_track): closure onset intervals are a shifted exponential
// (min_interval_s + an exponential of mean mean_interval_s − min_interval_s),
// each blink a linear close over closing_s and a linear reopening over
// opening_s. Defaults: 17.1 blinks/min (mean interval 3.5 s), close to the
// 17/min Bentivoglio et al. (1997, Movement Disorders 12:1028) measured at
// rest; 0.22 s per blink.
Layer blink_layer(std::size_t frames, double fps, const BlinkSettings& settings);

// Gaze: fixation on the camera with small saccades. Fixation durations are a
// shifted exponential (min_fixation_s + exponential, mean
// mean_fixation_s); each saccade goes to a point round the camera at an
// amplitude drawn from an exponential of mean mean_amplitude_deg (truncated
// at max_amplitude_deg from the camera) in a uniform direction, or with
// probability return_probability back to the camera when away from it; its
// duration follows the saccadic main sequence, 21 ms + 2.2 ms per degree
// (Carpenter 1988, "Movements of the Eyes"), with a smooth (raised-cosine)
// profile. The model's form (saccade frequency falling off exponentially
// with amplitude, gaze held between saccades, the main sequence for their
// durations) follows Lee, Badler & Badler (2002, "Eyes alive", SIGGRAPH);
// the default values (mean amplitude 2.5°, mean fixation 1.2 s) are our
// choice for a talking face looking at its viewer, not their fitted values.
struct GazeSettings {
    std::uint64_t seed = 1;
    double mean_fixation_s = 1.2;
    double min_fixation_s = 0.3;
    double mean_amplitude_deg = 2.5;
    double max_amplitude_deg = 8.0;
    double return_probability = 0.6;
    double vertical_scale = 0.6;  // vertical saccades are smaller than horizontal ones
};

// One saccade of a gaze track (for statistics and tests).
struct Saccade {
    double onset_s = 0.0;
    double duration_s = 0.0;
    double amplitude_deg = 0.0;             // angular size of the jump
    double to_left_deg = 0.0, to_up_deg = 0.0;  // where it lands (camera = 0, 0)
};
// The saccades of a gaze track over duration_s.
std::vector<Saccade> gaze_saccades(double duration_s, const GazeSettings& settings);
// The gaze direction (degrees left, up from the camera) at each frame.
std::vector<std::array<double, 2>> gaze_track_deg(std::size_t frames, double fps, const GazeSettings& settings);
// The gaze layer on a head: degrees → the gaze channels by the rig's gaze
// unit (gaze_unit_deg; a head without gaze transforms: the layer sets nothing).
Layer gaze_layer(std::size_t frames, double fps, const GazeSettings& settings, double gaze_unit_deg);
// The degrees one unit of the rig's gaze_left channel turns the eyes (0 when
// the rig has no gaze transforms).
double gaze_unit_deg(const Head& head);

// Small idle head motion: for each axis (pitch, yaw, roll) a sum of three
// sinusoids at seeded frequencies in 0.05–0.4 Hz with seeded phases,
// scaled to the axis's RMS angle. The amplitudes are our choice for a
// speaker at rest (about a degree), not measured values.
struct HeadMotionSettings {
    std::uint64_t seed = 1;
    double pitch_rms_deg = 1.0;
    double yaw_rms_deg = 1.0;
    double roll_rms_deg = 0.5;
};
// The head rotation at each frame (pitch about x: positive nods down; yaw
// about y: positive turns to the speaker's left; roll about z).
std::vector<glm::quat> idle_head_motion(std::size_t frames, double fps, const HeadMotionSettings& settings);
// The quaternion of MPEG-4 head FAPs 48–50 (pitch, yaw, roll in radians).
glm::quat head_rotation_from_angles(double pitch_rad, double yaw_rad, double roll_rad);

// FAPs → channels on a head: the FAPUs of the head (mesh units) and each
// channel's reach (the largest vertex displacement at ±1, mesh units).
// Mapping (docs/animation-layers.md): the jaw and lip FAPs through the
// least-squares inverse of synth/fap.h onto the 10 parameters; eyelids FAPs
// 19/20 (IRISD) → blink (1 = one iris diameter of lid travel); eyeball yaw
// and pitch 23–26 (AU) → gaze by the rig's gaze unit; inner brows 31/32
// (ENS, middle 33/34 where the inner are absent) → brow_inner_raise, outer
// 35/36 (middle likewise) → brow_outer_raise, squeeze 37/38 (ES) lowers the
// inner brows; cheek lift 41/42 (ENS) → cheek_raise; raise_tongue_tip 44 (MNS) →
// tongue_tip; head pitch, yaw, roll 48–50 (AU) → the head rotation. FAPs
// with no channel (puff cheeks 39/40, tongue 43/45–47, eyelid bottoms
// 21/22, pupils 27–30, nose, ears) are reported by unplayable_faps.
class FapPlayer {
public:
    explicit FapPlayer(const Head& head);
    // The channels (and rotation) one FAP frame sets.
    LayerFrame frame(const synth::FapFrame& fap) const;
    // Every frame of a stream (the jaw and lip FAPs decoded in one pass;
    // without `with_mouth` they are left out, as where the speech owns the mouth).
    std::vector<LayerFrame> play(const synth::FapStream& stream, bool with_mouth = true) const;
    // The FAPs set in a stream that the head cannot play, "19 close_t_l_eyelid", …
    std::vector<std::string> unplayable_faps(const synth::FapStream& stream) const;
    // Channels the head's rig lacks that the stream would drive.
    std::vector<std::string> missing_channels(const synth::FapStream& stream) const;

private:
    void upper_face(const synth::FapFrame& fap, LayerFrame& out) const;  // every FAP but the jaw and lips

    synth::FapUnits m_units;  // the head's FAPUs, mesh units
    double m_irisd = 0.0, m_ens = 0.0, m_es = 0.0, m_mns = 0.0;
    std::array<double, channel_count> m_reach_positive{}, m_reach_negative{};
    double m_gaze_unit_deg = 0.0;
    std::array<std::vector<int>, synth::param_count> m_param_faps;  // the FAPs each parameter drives
};

// A stream's frame at output frame k (of `fps`): the stream frame at or
// before k / fps; past the stream's end: nullopt.
std::optional<std::size_t> stream_frame_at(const synth::FapStream& stream, std::size_t k, double fps);

// A named expression's FAP set from an expressions file (JSON,
// "format": "avsi-expressions"; protocols/expressions.json): one frame.
synth::FapFrame named_expression(const std::filesystem::path& file, const std::string& name);
// The names an expressions file defines.
std::vector<std::string> expression_names(const std::filesystem::path& file);
std::filesystem::path default_expressions_file();

// ---- Settings (the protocol's [condition.layers]) ---------------------------

enum class LayerKind { Blink, Gaze, HeadMotion, Expression, Fap };
std::string_view to_string(LayerKind kind);

// One configured layer besides speech.
struct LayerSpec {
    LayerKind kind = LayerKind::Blink;
    std::optional<double> weight;
    std::array<std::optional<double>, feature_group_count> group_weights{};
    // HeadMotion: "idle", "fap" (FAPs 48–50 of `file`) or "quaternions"
    // (CSV time_s,w,x,y,z in `file`); Expression: the expression's name, or
    // empty with a FAP `file`.
    std::string source;
    std::filesystem::path file;  // resolved; empty when none
    GazeSettings gaze;           // Gaze (its seed set per stimulus)
    HeadMotionSettings head;     // HeadMotion idle (likewise)
    BlinkSettings blink;         // Blink: the rates (seed per stimulus)
};

struct LayerSettings {
    bool configured = false;        // a [condition.layers] table was given
    bool speech_owns_mouth = true;
    std::optional<double> speech_weight;
    std::array<std::optional<double>, feature_group_count> speech_group_weights{};
    std::vector<LayerSpec> layers;  // in stack order (blink first unless turned off)
    std::filesystem::path expressions_file = default_expressions_file();

    // The default stack of a model condition: speech + blinks.
    static LayerSettings speech_only();
};

// Reads a [condition.layers] table (or [layers] of a layers file); bad
// values, unknown keys, unknown expression names and unreadable files are
// added to `problems` with file:line:col and field. `base_dir` resolves
// relative paths. An absent section gives speech_only().
LayerSettings parse_layer_settings(const ConfigSection& section, const std::filesystem::path& base_dir,
                                   DiagnosticList& problems);
// The settings as JSON (kinds, weights, sources, each file's SHA-256), for
// a stimulus's input hash: a change of any layer or layer file changes it.
std::string layer_settings_json(const LayerSettings& settings);

// Reads a layers file: a TOML file with a [layers] table (`avsi render --layers`).
LayerSettings read_layer_settings(const std::filesystem::path& path);

// Per-stimulus seeds of the seeded layers (blink, gaze, idle head motion).
struct LayerSeeds {
    std::uint64_t blink = 1, gaze = 1, head = 1;
};

// ---- The one call ---------------------------------------------------------

// What animate returns: one pose per frame (head rotation included) and
// the stack's record for a manifest.
struct Animation {
    std::vector<Pose> poses;
    std::vector<std::string> warnings;  // channels the head lacks, FAPs it cannot play
    std::string record_json;            // kinds, seeds, weights, files with SHA-256 (JSON array)
};

// The per-frame poses of a stimulus: the speech layer from `trajectory`
// (with `phones`: the tongue tip) and the layers of `settings` at the
// trajectory's frame rate, blended (blend_frame). Throws InputError for an
// unreadable or malformed layer file.
Animation animate(const Head& head, const synth::Trajectory& trajectory, const PhoneSequence* phones,
                  const LayerSettings& settings, const LayerSeeds& seeds = {});

}  // namespace avsi::stimuli
