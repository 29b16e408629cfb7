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
#include "avsi/synth/trajectory.h"

namespace avsi::experiment {

// A loaded stimulus: its per-frame poses, trajectory, phones and audio.
struct PlayMedia {
    std::string title;
    synth::Trajectory trajectory;
    std::vector<stimuli::Pose> poses;  // one per trajectory frame
    PhoneSequence phones;              // may be empty
    std::vector<std::string> visemes;  // the viseme name of each phone
    std::vector<float> audio;          // mono; silence of the video's length when there is no audio
    int sample_rate_hz = 48000;
    std::filesystem::path head_gltf;   // a protocol's own head, if any
    std::filesystem::path head_obj;
    std::filesystem::path head_rig;
    int frame_count() const { return static_cast<int>(poses.size()); }
    double fps() const { return trajectory.fps; }
};

// The one place the player's animation comes from: the pose of every frame
// of a speech trajectory, with the seeded blinks and (given phones) the
// tongue tip, as the stimulus builder renders them (animation.h).
std::vector<stimuli::Pose> animation_poses(const synth::Trajectory& trajectory, const PhoneSequence* phones,
                                           const stimuli::BlinkSettings& blinks);

// Loads what `source` names. Throws UsageError for a wrong combination of
// options and InputError (file:line field) for missing or bad files.
PlayMedia load_play_media(const PlaySource& source);

}  // namespace avsi::experiment
