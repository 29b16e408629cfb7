// Optical markers → the 10 articulatory parameters on a head's rig, in the
// reference study's three steps (Beskow 2004 §3.2–3.5):
//
// 1. Head motion (§3.2): per frame, the rigid transform (rotation and
//    translation, least squares: Kabsch's SVD solution) taking the frame's
//    reference markers (the spectacle frame) to their positions in the
//    reference frame is applied to every marker. A frame with fewer than
//    `min_reference_markers` of them seen cannot be placed and is not fitted.
// 2. Orientation fit (§3.4, eq. 1): the similarity transform (3 translations,
//    3 rotations, 1 scale: 7 parameters) taking the strategic markers of the
//    reference frame onto their surface points on the model at rest, by
//    least squares (Umeyama 1991's closed form; eq. 1 sums distances, this
//    sums squared distances), applied to every frame.
// 3. Shape fit (§3.5, eq. 2–3): each face marker's virtual marker q(y) is tied
//    to its triangle so that it coincides with the marker in the reference
//    frame (the reference pose: relaxed face, jaw and lips closed, so the
//    model's rest); per frame, the parameters y within their ranges
//    (parameters.h) minimise Σ |q_i(y) − p_i|² over the markers seen (eq. 3
//    sums distances), by Ceres (Levenberg-Marquardt with bounds, central-
//    difference Jacobians of the rig), warm-started from the previous frame.
//    Frames are fitted in chunks of `chunk_frames` (each chain starting from
//    rest), so the result does not depend on the thread count.
// Markers of the recording the layout does not name, and layout markers the
// recording lacks, are listed in `notes`; dropouts are counted per marker.
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "avsi/learn/articulatory_corpus.h"
#include "avsi/learn/markers.h"
#include "avsi/synth/marker_model.h"

namespace avsi::learn {

struct MarkerFitSettings {
    // The reference frame (the reference pose); default: the first frame in
    // which every reference and strategic marker is seen.
    std::optional<std::size_t> reference_frame;
    std::size_t min_reference_markers = 3;
    std::size_t min_face_markers = 4;      // a frame with fewer seen is not fitted
    double derivative_step = 1e-3;         // central differences, normalised units
    int max_iterations = 30;
    std::size_t chunk_frames = 600;        // warm-start chain length
    std::size_t threads = 0;               // 0: the hardware's
};

// x ↦ scale · R x + translation (R row-major).
struct Similarity {
    double scale = 1.0;
    std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::array<double, 3> translation{};
    std::array<double, 3> apply(const double* x) const;
};

struct MarkerFitResult {
    ParamTrack track;                       // every parameter present; NaN where a frame was not fitted
    std::vector<std::string> markers;       // the face markers fitted, in layout order
    std::vector<double> residual_mm;        // frames × markers: |q(y) − p| in mm; NaN where not seen
    Similarity orientation;                 // the orientation fit (recording, head-fixed → model)
    double orientation_rms_mm = 0.0;        // its RMS error over the strategic markers
    std::size_t reference_frame = 0;
    std::vector<std::size_t> dropouts;      // per fitted marker: frames it was not seen
    std::size_t frames_unplaced = 0;        // too few reference markers: not fitted
    std::size_t frames_too_few_markers = 0; // too few face markers: not fitted
    std::vector<std::string> notes;         // markers left out or not in the layout

    double residual(std::size_t frame, std::size_t marker) const { return residual_mm[frame * markers.size() + marker]; }
};

// Fits a recording to a head's marker model (see the file comment). Throws
// InputError naming `source` when the recording lacks what the fit needs
// (three reference markers, three strategic markers, a reference frame).
MarkerFitResult fit_markers(const MarkerRecording& recording, const synth::MarkerModel& model,
                            const MarkerFitSettings& settings, const std::string& source);

// The least-squares rigid (with_scale false) or similarity transform taking
// points `from` onto `to` (n × 3 each, n ≥ 3): Kabsch / Umeyama.
Similarity fit_similarity(const std::vector<double>& from, const std::vector<double>& to, bool with_scale);

// `time_s,<marker>…` with the residual in mm per frame (empty where not seen).
void write_fit_residuals_csv(const std::filesystem::path& path, const MarkerFitResult& fit);
// An SVG of the residual over time: per frame the RMS and the largest over
// the markers, and each marker's RMS as a bar beside it.
void write_fit_residual_plot(const std::filesystem::path& path, const MarkerFitResult& fit, const std::string& title);

}  // namespace avsi::learn
