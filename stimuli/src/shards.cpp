// Sharded stimulus builds: the split, the shard manifests, the merge's
// checks and the Slurm scripts (see shards.h and build_shards.h).
#include "build_shards.h"

#include <algorithm>
#include <cctype>
#include <map>
#include <set>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"

namespace avsi::stimuli {

namespace {

using nlohmann::json;

constexpr const char* shard_format = "avsi-stimuli-shard";
constexpr int shard_format_version = 1;

// The command that (re)builds a shard of this set, for messages.
std::string rerun_command(const std::filesystem::path& out_dir) {
    return fmt::format("avsi build-stimuli PROTOCOL --out {}", out_dir.string());
}

// A short form of a SHA-256 for messages.
std::string short_hash(const std::string& hash) { return hash.substr(0, 12); }

}  // namespace

std::filesystem::path shard_manifest_path(const std::filesystem::path& out_dir, ShardSpec shard) {
    return out_dir / "shards" / (shard.stem() + ".json");
}

namespace detail {

PlanIdentity plan_identity(const std::filesystem::path& protocol_path, const std::vector<PlannedStimulus>& stimuli,
                           const std::string& builder_version) {
    PlanIdentity id;
    id.protocol = protocol_path.filename().string();
    id.protocol_sha256 = sha256_file(protocol_path);
    std::string inputs;
    for (const auto& s : stimuli) inputs += s.path + " " + s.input_hash + "\n";
    id.inputs_sha256 = sha256_hex(inputs);
    id.builder = builder_version;
    id.avsi = avsi_version();
    return id;
}

double expected_duration_s(const Sentence& sentence, const Protocol& protocol) {
    if (protocol.corpus.audio != CorpusAudio::Tts && !sentence.labels.empty()) {
        const PhoneSequence phones = read_phones(sentence.labels);
        if (!phones.empty()) return phones.back().end_s;
    }
    const auto letters = std::count_if(sentence.text.begin(), sentence.text.end(),
                                       [](unsigned char c) { return std::isalpha(c) || c >= 0x80; });
    return 0.5 + static_cast<double>(letters) / 14.0;
}

namespace {

// The shard of each stimulus among `shards`.
std::vector<std::size_t> shard_of(const std::vector<PlannedStimulus>& stimuli, std::size_t shards) {
    std::vector<double> weights;
    std::vector<std::size_t> sentence_of;
    std::map<std::string, std::size_t> sentence_index;
    for (const auto& s : stimuli) {
        weights.push_back(s.expected_frames);
        sentence_of.push_back(sentence_index.emplace(s.sentence, sentence_index.size()).first->second);
    }
    return assign_grouped_shards(weights, sentence_of, shards);
}

}  // namespace

std::vector<bool> shard_members(const std::vector<PlannedStimulus>& stimuli, ShardSpec shard) {
    const std::vector<std::size_t> shards = shard_of(stimuli, shard.count);
    std::vector<bool> member(stimuli.size());
    for (std::size_t i = 0; i < stimuli.size(); ++i) member[i] = shards[i] == shard.index;
    return member;
}

ShardPlan shard_plan(const std::vector<PlannedStimulus>& stimuli, std::size_t shards) {
    const std::vector<std::size_t> shard = shard_of(stimuli, shards);
    ShardPlan plan;
    plan.stimuli = stimuli.size();
    plan.stimuli_per_shard.assign(shards, 0);
    plan.expected_frames_per_shard.assign(shards, 0.0);
    std::vector<std::set<std::string>> sentences(shards);
    for (std::size_t i = 0; i < stimuli.size(); ++i) {
        plan.expected_frames += stimuli[i].expected_frames;
        ++plan.stimuli_per_shard[shard[i]];
        plan.expected_frames_per_shard[shard[i]] += stimuli[i].expected_frames;
        sentences[shard[i]].insert(stimuli[i].sentence);
    }
    for (const auto& s : sentences) plan.sentences_per_shard.push_back(s.size());
    return plan;
}

std::map<std::string, json> shard_entries(const std::filesystem::path& out_dir, ShardSpec shard) {
    std::map<std::string, json> entries;
    const auto path = shard_manifest_path(out_dir, shard);
    if (!std::filesystem::exists(path)) return entries;
    try {
        const json j = read_json_file(path);
        for (const auto& e : j.at("stimuli")) entries[e.at("path").get<std::string>()] = e;
    } catch (const std::exception&) {
        log_warning("{}: unreadable shard manifest, rebuilding the shard's stimuli", path.string());
        entries.clear();
    }
    return entries;
}

void write_shard_manifest(const std::filesystem::path& out_dir, ShardSpec shard, const PlanIdentity& id,
                          const std::vector<json>& entries) {
    const json manifest = {{"format", shard_format},
                           {"version", shard_format_version},
                           {"shard", shard.index},
                           {"shards", shard.count},
                           {"protocol", id.protocol},
                           {"protocol_sha256", id.protocol_sha256},
                           {"inputs_sha256", id.inputs_sha256},
                           {"builder", id.builder},
                           {"avsi", id.avsi},
                           {"stimuli", entries}};
    write_text_file(shard_manifest_path(out_dir, shard), manifest.dump(2) + "\n");
    log_info("build-stimuli: shard {}: {} stimuli listed in {}; once every shard is built, --merge writes the manifest",
             shard.text(), entries.size(), shard_manifest_path(out_dir, shard).string());
}

namespace {

// A shard manifest's own fields against the plan's identity; its findings
// go to `problems` under the file's name. Returns false when its entries
// cannot be trusted (another split, protocol, inputs or avsi).
bool check_shard_header(const json& j, const std::string& file, ShardSpec expected, const PlanIdentity& id,
                        const std::filesystem::path& out_dir, DiagnosticList& problems) {
    const std::string field = "shard " + expected.text();
    const auto add = [&](const std::string& message) { problems.add(file, 0, 0, field, message); };
    if (!j.is_object() || json_string(j, "format") != shard_format) {
        add(fmt::format("expected a shard manifest (\"format\": \"{}\"), got {}", shard_format,
                        j.is_object() ? "\"format\": " + j.value("format", json()).dump() : "no JSON object"));
        return false;
    }
    const json version = j.value("version", json());
    if (version != shard_format_version) {
        add(fmt::format("expected version {}, got {}", shard_format_version, version.dump()));
        return false;
    }
    const json k = j.value("shard", json()), n = j.value("shards", json());
    if (k != expected.index || n != expected.count) {
        add(fmt::format("claims to be shard {}/{} but is named {}: two shards would claim the same stimuli; remove "
                        "it and rebuild with --shard {}",
                        k.dump(), n.dump(), expected.stem() + ".json", expected.text()));
        return false;
    }
    const std::string rebuild = fmt::format("; rebuild it with {} --shard {}", rerun_command(out_dir), expected.text());
    if (json_string(j, "protocol_sha256") != id.protocol_sha256) {
        add(fmt::format("foreign: built from another protocol ({} with SHA-256 {}…, this protocol is {} with {}…){}",
                        json_string(j, "protocol", "?"), short_hash(json_string(j, "protocol_sha256")), id.protocol,
                        short_hash(id.protocol_sha256), rebuild));
        return false;
    }
    if (json_string(j, "builder") != id.builder || json_string(j, "avsi") != id.avsi) {
        add(fmt::format("stale: built by avsi {} (builder {}), this is avsi {} (builder {}){}", json_string(j, "avsi", "?"),
                        json_string(j, "builder", "?"), id.avsi, id.builder, rebuild));
        return false;
    }
    if (json_string(j, "inputs_sha256") != id.inputs_sha256) {
        add("stale: the protocol's inputs (corpus, models, head, voice or build options) differ from those it was "
            "built with" + rebuild);
        return false;
    }
    if (!j.contains("stimuli") || !j["stimuli"].is_array()) {
        add("expected a \"stimuli\" array of manifest entries");
        return false;
    }
    return true;
}

}  // namespace

std::vector<json> merge_shard_entries(const std::filesystem::path& out_dir, const PlanIdentity& id,
                                      const std::vector<PlannedStimulus>& stimuli) {
    const ShardFiles files = find_shard_files(out_dir / "shards", "", ".json", rerun_command(out_dir));
    std::map<std::string, std::size_t> index_of;  // planned path → plan index
    for (std::size_t i = 0; i < stimuli.size(); ++i) index_of[stimuli[i].path] = i;
    std::vector<json> entries(stimuli.size());
    std::vector<std::string> claimed_by(stimuli.size());
    DiagnosticList problems;
    for (std::size_t k = 0; k < files.count; ++k) {
        const std::string file = files.files[k].string();
        const ShardSpec shard{k, files.count};
        json j;
        try {
            j = read_json_file(files.files[k]);
        } catch (const InputError& e) {
            for (const auto& d : e.diagnostics()) problems.add(d);
            continue;
        }
        if (!check_shard_header(j, file, shard, id, out_dir, problems)) continue;
        std::size_t n = 0;
        for (const auto& e : j["stimuli"]) {
            const std::string where = fmt::format("stimuli[{}]", n++);
            const std::string path = json_string(e, "path");
            const auto it = index_of.find(path);
            if (it == index_of.end()) {
                problems.add(file, 0, 0, where,
                             fmt::format("foreign: the protocol asks for no stimulus \"{}\"", excerpt(path)));
                continue;
            }
            const std::size_t i = it->second;
            if (!claimed_by[i].empty()) {
                problems.add(file, 0, 0, path,
                             fmt::format("duplicated: also claimed by {}", std::filesystem::path(claimed_by[i]).filename().string()));
                continue;
            }
            claimed_by[i] = file;
            if (json_string(e, "input_sha256") != stimuli[i].input_hash) {
                problems.add(file, 0, 0, path, "stale: built from other inputs than the protocol's now");
                continue;
            }
            for (const std::string& f : {path, stimuli[i].wav})
                if (!std::filesystem::exists(out_dir / f))
                    problems.add(file, 0, 0, path,
                                 fmt::format("{} is not in {}: was the task's --out on a disk of its node rather "
                                             "than the shared filesystem?",
                                             f, out_dir.string()));
            entries[i] = e;
        }
    }
    std::size_t unclaimed = 0;
    for (std::size_t i = 0; i < stimuli.size(); ++i)
        if (claimed_by[i].empty() && ++unclaimed <= 10)
            problems.add((out_dir / "shards").string(), 0, 0, stimuli[i].path, "missing: in no shard manifest");
    if (unclaimed > 10)
        problems.add((out_dir / "shards").string(), 0, 0, "stimuli",
                     fmt::format("missing: {} more stimuli in no shard manifest", unclaimed - 10));
    problems.throw_if_any();
    return entries;
}

}  // namespace detail

SlurmScripts write_build_slurm_scripts(const BuildSettings& settings, const SlurmSettings& slurm,
                                       const std::filesystem::path& path, const std::filesystem::path& avsi,
                                       const std::vector<std::string>& build_options) {
    validate_slurm_settings(slurm);
    const ShardPlan split = plan_shards(settings, slurm.shards);
    const auto protocol = std::filesystem::absolute(settings.protocol_path).lexically_normal();
    const auto out = std::filesystem::absolute(settings.out_dir).lexically_normal();
    const std::vector<std::string> head = {std::filesystem::absolute(avsi).lexically_normal().string(),
                                           "build-stimuli", protocol.string(), "--out", out.string()};
    const auto command = [&](std::vector<std::string> args) {
        std::vector<std::string> line = head;
        line.insert(line.end(), args.begin(), args.end());
        line.insert(line.end(), build_options.begin(), build_options.end());
        return line;
    };
    SlurmJob job;
    std::string name = "avsi-stimuli-";
    const std::string stem = protocol.stem().string();
    for (const char c : stem) name += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
    if (name.size() > 40) name.resize(40);
    job.name = name;
    job.what = fmt::format("avsi build-stimuli {} --out {}: {} stimuli, about {:.0f} frames, in {} shards", protocol.string(),
                           out.string(), split.stimuli, split.expected_frames, slurm.shards);
    job.log_dir = out / "slurm";
    job.task = command({"--shard", "{shard}", "--jobs", "{cpus}"});
    job.merge = {command({"--merge", "--jobs", "{cpus}"}), command({"--verify", "--jobs", "{cpus}"})};
    const SlurmScripts scripts = write_slurm_scripts(path, job, slurm);
    const auto most = std::max_element(split.expected_frames_per_shard.begin(), split.expected_frames_per_shard.end());
    std::size_t speech = 0;
    for (const std::size_t n : split.sentences_per_shard) speech += n;
    log_info("build-stimuli: {} stimuli, about {:.0f} frames, in {} shards of about {:.0f} frames (the largest {:.0f}); "
             "{} sentences' speech made over all shards",
             split.stimuli, split.expected_frames, slurm.shards, split.expected_frames / double(slurm.shards),
             most == split.expected_frames_per_shard.end() ? 0.0 : *most, speech);
    return scripts;
}

}  // namespace avsi::stimuli
