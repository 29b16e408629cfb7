// The viseme-set editor behind `avsi play --edit-visemes set.json` (the
// Charisma paper's viseme editor, seed 000 §3): select a viseme, change its
// articulatory targets and its outer-lip contour (width, height) while the
// face shows it, see every viseme's MPEG-4 Cohen-Massaro α recomputed from
// the ellipse areas π·w·h (eq. 8, normalised over the set as the model does),
// move phones between visemes, undo, compare with the file on disk, and save
// the set as the JSON the model reads (synth/mpeg4_cohen_massaro.h). This
// class is the editor's state without a window, so tests drive it directly.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/synth/mpeg4_cohen_massaro.h"

namespace avsi::experiment {

class VisemeEditor {
public:
    // Loads the set (InputError naming file and field if it is bad).
    explicit VisemeEditor(std::filesystem::path path);

    const synth::VisemeSet& set() const { return m_set; }
    const std::filesystem::path& path() const { return m_path; }
    std::size_t selected() const { return m_selected; }
    const synth::Viseme& selected_viseme() const { return m_set.visemes[m_selected]; }
    void select(std::size_t index);
    // Selects by viseme name; throws UsageError (with the names) if there is none.
    void select(const std::string& name);
    // The viseme index of a name, or throws UsageError listing the names.
    std::size_t index_of(const std::string& name) const;

    // Remembers the current set for undo; call once before an edit (a slider
    // drag is one edit). The setters below do not call it themselves.
    void begin_edit();
    // Remembers `before` for undo (a slider drag that started from it).
    void remember(synth::VisemeSet before);
    // Sets the selected viseme's target of `param`; throws UsageError outside its range.
    void set_target(synth::Param param, double value);
    // Sets the selected viseme's outer-lip contour width / height (mm, (0, 200]).
    void set_width_mm(double width_mm);
    void set_height_mm(double height_mm);
    // Maps `phone` (a project phone symbol) to viseme `viseme`, removing it from its old one.
    void map_phone(const std::string& phone, std::size_t viseme);
    // Restores the set before the last edit; false when there is nothing to undo.
    bool undo();
    std::size_t undo_depth() const { return m_undo.size(); }

    // α of every viseme (eq. 8 normalised as the model does).
    std::vector<double> alphas() const { return m_set.normalised_areas(); }
    // The differences from the file on disk, one line each
    // ("p_b_m.targets.jaw_rotation: 0.1 on disk, 0.3 here"); empty when equal.
    std::vector<std::string> diff_with_disk() const;
    // True when the set differs from what was last loaded or saved.
    bool modified() const;

    // Writes the set (atomically) to `path` (default: the file it came from)
    // and checks that load_viseme_set reads it back to the same set.
    void save(const std::filesystem::path& path = {});

private:
    std::filesystem::path m_path;
    synth::VisemeSet m_set;
    std::string m_saved_text;  // viseme_set_json_text of the set as last loaded or saved
    std::size_t m_selected = 0;
    std::vector<synth::VisemeSet> m_undo;
};

// The differences between two viseme sets, one line each (names from `a`'s visemes).
std::vector<std::string> viseme_set_diff(const synth::VisemeSet& on_disk, const synth::VisemeSet& edited);

}  // namespace avsi::experiment
