// The viseme-set editor's state (see viseme_editor.h).
#include "avsi/experiment/viseme_editor.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::experiment {

namespace fs = std::filesystem;

namespace {

std::string names_of(const synth::VisemeSet& set) {
    std::string out;
    for (const auto& v : set.visemes) out += (out.empty() ? "" : ", ") + v.name;
    return out;
}

std::string diff_number(double v) { return fmt::format("{:g}", v); }

}  // namespace

VisemeEditor::VisemeEditor(fs::path path)
    : m_path(std::move(path)), m_set(synth::load_viseme_set(m_path)), m_saved_text(synth::viseme_set_json_text(m_set)) {}

void VisemeEditor::select(std::size_t index) {
    AVSI_ASSERT(index < m_set.visemes.size());
    m_selected = index;
}

std::size_t VisemeEditor::index_of(const std::string& name) const {
    for (std::size_t i = 0; i < m_set.visemes.size(); ++i)
        if (m_set.visemes[i].name == name) return i;
    throw UsageError(fmt::format("no viseme \"{}\" in {} (the visemes are {})", name, m_path.string(), names_of(m_set)));
}

void VisemeEditor::select(const std::string& name) { m_selected = index_of(name); }

void VisemeEditor::begin_edit() { m_undo.push_back(m_set); }

void VisemeEditor::remember(synth::VisemeSet before) { m_undo.push_back(std::move(before)); }

void VisemeEditor::set_target(synth::Param param, double value) {
    const auto& info = synth::param_info(param);
    if (!std::isfinite(value) || value < info.min || value > info.max)
        throw UsageError(fmt::format("{}: expected a value in [{:g}, {:g}], got {:g}", info.name, info.min, info.max, value));
    m_set.visemes[m_selected].targets[synth::index(param)] = value;
}

void VisemeEditor::set_width_mm(double width_mm) {
    if (!std::isfinite(width_mm) || width_mm <= 0.0 || width_mm > 200.0)
        throw UsageError(fmt::format("width_mm: expected a value in (0, 200], got {:g}", width_mm));
    m_set.visemes[m_selected].width_mm = width_mm;
}

void VisemeEditor::set_height_mm(double height_mm) {
    if (!std::isfinite(height_mm) || height_mm <= 0.0 || height_mm > 200.0)
        throw UsageError(fmt::format("height_mm: expected a value in (0, 200], got {:g}", height_mm));
    m_set.visemes[m_selected].height_mm = height_mm;
}

void VisemeEditor::map_phone(const std::string& phone, std::size_t viseme) {
    AVSI_ASSERT(viseme < m_set.visemes.size());
    // load_viseme_set maps every project phone, so the map holds them all.
    const auto it = m_set.phone_to_viseme.find(phone);
    if (it == m_set.phone_to_viseme.end())
        throw UsageError(fmt::format("\"{}\" is not a project phone symbol (ARPAbet in capitals, silence sil)", phone));
    if (it->second == viseme) return;
    auto& old_phones = m_set.visemes[it->second].phones;
    old_phones.erase(std::remove(old_phones.begin(), old_phones.end(), phone), old_phones.end());
    m_set.visemes[viseme].phones.push_back(phone);
    it->second = viseme;
}

bool VisemeEditor::undo() {
    if (m_undo.empty()) return false;
    m_set = std::move(m_undo.back());
    m_undo.pop_back();
    return true;
}

bool VisemeEditor::modified() const { return synth::viseme_set_json_text(m_set) != m_saved_text; }

std::vector<std::string> VisemeEditor::diff_with_disk() const {
    if (!fs::exists(m_path)) return {fmt::format("{} is not on disk (deleted since it was opened)", m_path.string())};
    try {
        return viseme_set_diff(synth::load_viseme_set(m_path), m_set);
    } catch (const InputError& e) {
        return {fmt::format("the file on disk no longer reads as a viseme set: {}", e.first().format())};
    }
}

void VisemeEditor::save(const fs::path& path) {
    const fs::path target = path.empty() ? m_path : path;
    const std::string text = synth::viseme_set_json_text(m_set);
    write_text_file(target, text);
    // The model must read back exactly what was edited.
    const synth::VisemeSet back = synth::load_viseme_set(target);
    const auto differences = viseme_set_diff(back, m_set);
    if (!differences.empty())
        throw InputError(target, 0, 0, "visemes",
                         fmt::format("the saved set reads back differently: {}", differences.front()));
    if (target == m_path) m_saved_text = text;
}

std::vector<std::string> viseme_set_diff(const synth::VisemeSet& on_disk, const synth::VisemeSet& edited) {
    std::vector<std::string> out;
    if (on_disk.name != edited.name) out.push_back(fmt::format("name: \"{}\" on disk, \"{}\" here", on_disk.name, edited.name));
    if (on_disk.source != edited.source) out.push_back("source: changed");
    if (on_disk.visemes.size() != edited.visemes.size()) {
        out.push_back(fmt::format("visemes: {} on disk, {} here", on_disk.visemes.size(), edited.visemes.size()));
        return out;
    }
    for (std::size_t i = 0; i < edited.visemes.size(); ++i) {
        const auto& a = on_disk.visemes[i];
        const auto& b = edited.visemes[i];
        const std::string name = a.name == b.name ? b.name : fmt::format("{} (on disk {})", b.name, a.name);
        if (a.id != b.id) out.push_back(fmt::format("{}.id: {} on disk, {} here", name, a.id, b.id));
        if (a.width_mm != b.width_mm)
            out.push_back(fmt::format("{}.width_mm: {} on disk, {} here", name, diff_number(a.width_mm), diff_number(b.width_mm)));
        if (a.height_mm != b.height_mm)
            out.push_back(fmt::format("{}.height_mm: {} on disk, {} here", name, diff_number(a.height_mm), diff_number(b.height_mm)));
        for (const auto& info : synth::params()) {
            const double x = a.targets[synth::index(info.param)], y = b.targets[synth::index(info.param)];
            if (x != y) out.push_back(fmt::format("{}.targets.{}: {} on disk, {} here", name, info.name, diff_number(x), diff_number(y)));
        }
    }
    for (const auto& [phone, index] : edited.phone_to_viseme) {
        const auto it = on_disk.phone_to_viseme.find(phone);
        if (it == on_disk.phone_to_viseme.end() || it->second != index)
            out.push_back(fmt::format("phone {}: viseme {} on disk, {} here", phone,
                                      it == on_disk.phone_to_viseme.end() ? std::string("none")
                                                                          : on_disk.visemes[it->second].name,
                                      edited.visemes[index].name));
    }
    return out;
}

}  // namespace avsi::experiment
