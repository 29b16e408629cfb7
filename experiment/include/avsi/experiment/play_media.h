// What `avsi play` plays, loaded: the per-frame poses of a trajectory, FAP
// stream or stimulus definition (the builder's trajectory, blinks and tongue
// tip), its phones with their visemes, and its audio. Kept apart from
// player.h because it names the stimuli module's types.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/experiment/player.h"
#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/head.h"
#include "avsi/stimuli/layers.h"
#include "avsi/synth/trajectory.h"

namespace avsi::experiment {

// A loaded stimulus: its per-frame poses, trajectory, phones and audio.
struct PlayMedia {
    std::string title;
    synth::Trajectory trajectory;
    std::vector<stimuli::Pose> poses;  // one per trajectory frame (animate_play_media)
    stimuli::LayerSettings layers = stimuli::LayerSettings::speech_only();  // the stimulus's stack
    stimuli::LayerSeeds layer_seeds;
    PhoneSequence phones;              // may be empty
    std::vector<std::string> visemes;  // the viseme name of each phone
    std::vector<float> audio;          // mono; silence of the video's length when there is no audio
    int sample_rate_hz = 48000;
    std::filesystem::path head_gltf;   // a protocol's own head, if any
    std::filesystem::path head_obj;
    std::filesystem::path head_rig;
    int frame_count() const { return static_cast<int>(trajectory.size()); }
    double fps() const { return trajectory.fps; }
};

// Loads what `source` names (poses not yet made: animate_play_media). Throws
// UsageError for a wrong combination of options and InputError (file:line
// field) for missing or bad files.
PlayMedia load_play_media(const PlaySource& source);

// The one place the player's animation comes from: the pose of every frame
// through the animation layers (layers.h) on `head`, as the stimulus builder
// renders them — a stimulus definition's own stack and seeds, or speech and
// the seeded blinks for a trajectory or FAP stream. Returns the layers'
// warnings (channels the head lacks).
std::vector<std::string> animate_play_media(const stimuli::Head& head, PlayMedia& media);

}  // namespace avsi::experiment
