// glTF heads with ARKit-named morph targets (gltf_head.h), through tinygltf
// (Debian's libtinygltf-dev, a shared library: no TINYGLTF_IMPLEMENTATION
// here). The loaded head becomes the same Head as an OBJ + rig: its morph
// targets become blendshape transforms by the mapping, and the rig document
// assembled from the asset's avsi extras goes through the one rig reader.
#include "avsi/stimuli/gltf_head.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <set>
#include <tuple>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "avsi/core/checks.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/synth/parameters.h"
#include "rig_reader.h"
#include "smoothstep.h"

namespace avsi::stimuli {

using nlohmann::json;

namespace {

constexpr float mm_per_metre = 1000.0f;

std::vector<std::string> gltf_channel_names() {
    std::vector<std::string> names;
    for (const auto& info : synth::params()) names.emplace_back(info.name);
    names.emplace_back("blink");
    names.emplace_back("tongue_tip");
    names.emplace_back("gaze_left");
    names.emplace_back("gaze_up");
    return names;
}

// The channel's range ends (blink and tongue tip: 0 to 1; gaze: −1 to 1).
std::pair<double, double> channel_range(const std::string& channel) {
    if (const auto p = synth::param_from_name(channel)) return {synth::param_info(*p).min, synth::param_info(*p).max};
    if (channel == "gaze_left" || channel == "gaze_up") return {-1.0, 1.0};
    return {0.0, 1.0};
}

// ---- Reading accessors ------------------------------------------------------

const tinygltf::Accessor& accessor_at(const tinygltf::Model& model, int index, const std::filesystem::path& path) {
    if (index < 0 || static_cast<std::size_t>(index) >= model.accessors.size())
        throw InputError(path.string(), 0, 0, "accessors",
                         "expected an accessor index in [0, " + std::to_string(model.accessors.size()) + "), got " + std::to_string(index));
    return model.accessors[static_cast<std::size_t>(index)];
}

// `count` elements of `element_bytes` bytes in buffer view `index` from
// `offset`, `stride` apart (the view's byteStride, else `tight` or the
// element's size): where they start, checked to lie within the view and the
// view within its buffer (no overflow for any count).
struct ViewBytes {
    const unsigned char* data = nullptr;
    std::size_t stride = 0;
};
ViewBytes view_bytes(const tinygltf::Model& model, int index, std::size_t offset, std::size_t count, std::size_t element_bytes,
                     const std::string& name, const std::filesystem::path& path, std::size_t tight = 0) {
    if (index < 0 || static_cast<std::size_t>(index) >= model.bufferViews.size())
        throw InputError(path.string(), 0, 0, name + ".bufferView",
                         "expected a buffer view index in [0, " + std::to_string(model.bufferViews.size()) + "), got " + std::to_string(index));
    const auto& view = model.bufferViews[static_cast<std::size_t>(index)];
    if (view.buffer < 0 || static_cast<std::size_t>(view.buffer) >= model.buffers.size())
        throw InputError(path.string(), 0, 0, "bufferViews[" + std::to_string(index) + "].buffer", "expected a buffer index");
    const auto& buffer = model.buffers[static_cast<std::size_t>(view.buffer)].data;
    if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset)
        throw InputError(path.string(), 0, 0, "bufferViews[" + std::to_string(index) + "]", "reaches beyond its buffer");
    const std::size_t stride = view.byteStride ? view.byteStride : (tight ? tight : element_bytes);
    const std::size_t length = view.byteLength;
    const bool fits = count == 0 || (offset <= length && element_bytes <= length - offset &&
                                     (stride == 0 || count - 1 <= (length - offset - element_bytes) / stride));
    if (!fits)
        throw InputError(path.string(), 0, 0, name,
                         std::to_string(count) + " elements reach beyond buffer view " + std::to_string(index) + " (" +
                             std::to_string(length) + " bytes)");
    return {buffer.data() + view.byteOffset + offset, stride};
}

// Accessor `index` as floats, `components` per element (normalized integer
// types scaled to [0, 1]); sparse accessors applied.
std::vector<float> read_floats(const tinygltf::Model& model, int index, int components, const std::filesystem::path& path) {
    const auto& a = accessor_at(model, index, path);
    const std::string name = "accessors[" + std::to_string(index) + "]";
    const int have = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type));
    if (have < components)
        throw InputError(path.string(), 0, 0, name + ".type",
                         "expected " + std::to_string(components) + " components, got " + std::to_string(have));
    const int size = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(a.componentType));
    if (size <= 0) throw InputError(path.string(), 0, 0, name + ".componentType", "expected a glTF component type, got " + std::to_string(a.componentType));
    const std::size_t element_bytes = std::size_t(size) * std::size_t(have);
    // The values come from a buffer view (the count bounded by its bytes) or
    // are zeros with sparse entries (the count bounded by a sane limit).
    constexpr std::size_t max_viewless_count = 10'000'000;
    if (a.bufferView < 0 && a.count > max_viewless_count)
        throw InputError(path.string(), 0, 0, name + ".count",
                         "expected at most " + std::to_string(max_viewless_count) + " elements without a buffer view, got " +
                             std::to_string(a.count));
    const auto view = a.bufferView >= 0 ? view_bytes(model, a.bufferView, a.byteOffset, a.count, element_bytes, name, path)
                                        : ViewBytes{};
    auto element = [&](const unsigned char* p, int c) -> float {
        switch (a.componentType) {
            case TINYGLTF_COMPONENT_TYPE_FLOAT: {
                float f;
                std::memcpy(&f, p + 4 * c, 4);
                return f;
            }
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return p[c] / (a.normalized ? 255.0f : 1.0f);
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
                std::uint16_t v;
                std::memcpy(&v, p + 2 * c, 2);
                return v / (a.normalized ? 65535.0f : 1.0f);
            }
            default:
                throw InputError(path.string(), 0, 0, name + ".componentType",
                                 "expected float, unsigned byte or unsigned short, got " + std::to_string(a.componentType));
        }
    };
    std::vector<float> out(a.count * static_cast<std::size_t>(components), 0.0f);
    for (std::size_t i = 0; view.data && i < a.count; ++i)
        for (int c = 0; c < components; ++c)
            out[i * std::size_t(components) + std::size_t(c)] = element(view.data + i * view.stride, c);
    if (a.sparse.isSparse) {
        const auto& sp = a.sparse;
        if (sp.count < 0 || static_cast<std::size_t>(sp.count) > a.count)
            throw InputError(path.string(), 0, 0, name + ".sparse.count",
                             "expected at most the accessor's " + std::to_string(a.count) + " elements, got " + std::to_string(sp.count));
        const int isize = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(sp.indices.componentType));
        if (isize != 1 && isize != 2 && isize != 4)
            throw InputError(path.string(), 0, 0, name + ".sparse.indices.componentType", "expected an unsigned integer type");
        const auto count = static_cast<std::size_t>(sp.count);
        const auto iv = view_bytes(model, sp.indices.bufferView, sp.indices.byteOffset, count, std::size_t(isize), name + ".sparse.indices", path, std::size_t(isize));
        const auto vv = view_bytes(model, sp.values.bufferView, sp.values.byteOffset, count, element_bytes, name + ".sparse.values", path, element_bytes);
        for (std::size_t k = 0; k < count; ++k) {
            const unsigned char* ip = iv.data + k * iv.stride;
            std::uint32_t target = 0;
            if (isize == 1) target = *ip;
            else if (isize == 2) { std::uint16_t v; std::memcpy(&v, ip, 2); target = v; }
            else std::memcpy(&target, ip, 4);
            if (target >= a.count) throw InputError(path.string(), 0, 0, name + ".sparse.indices", "an index is out of range");
            for (int c = 0; c < components; ++c) out[target * std::size_t(components) + std::size_t(c)] = element(vv.data + k * vv.stride, c);
        }
    }
    return out;
}

std::vector<std::uint32_t> read_indices(const tinygltf::Model& model, int index, const std::filesystem::path& path) {
    const auto& a = accessor_at(model, index, path);
    const std::string name = "accessors[" + std::to_string(index) + "]";
    const int size = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(a.componentType));
    if ((size != 1 && size != 2 && size != 4) || tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type)) != 1)
        throw InputError(path.string(), 0, 0, name, "expected scalar unsigned integer indices");
    if (a.bufferView < 0) throw InputError(path.string(), 0, 0, name + ".bufferView", "expected the indices' buffer view");
    const auto view = view_bytes(model, a.bufferView, a.byteOffset, a.count, std::size_t(size), name, path);
    std::vector<std::uint32_t> out(a.count);
    for (std::size_t i = 0; i < a.count; ++i) {
        const unsigned char* p = view.data + i * view.stride;
        if (size == 1) out[i] = *p;
        else if (size == 2) { std::uint16_t v; std::memcpy(&v, p, 2); out[i] = v; }
        else std::memcpy(&out[i], p, 4);
    }
    return out;
}

glm::mat4 node_matrix(const tinygltf::Node& node) {
    if (node.matrix.size() == 16) {
        glm::dmat4 m;
        std::memcpy(glm::value_ptr(m), node.matrix.data(), 16 * sizeof(double));
        return glm::mat4(m);
    }
    glm::mat4 m(1.0f);
    if (node.translation.size() == 3)
        m = glm::translate(m, glm::vec3(float(node.translation[0]), float(node.translation[1]), float(node.translation[2])));
    if (node.rotation.size() == 4)
        m *= glm::mat4_cast(glm::quat(float(node.rotation[3]), float(node.rotation[0]), float(node.rotation[1]), float(node.rotation[2])));
    if (node.scale.size() == 3) m = glm::scale(m, glm::vec3(float(node.scale[0]), float(node.scale[1]), float(node.scale[2])));
    return m;
}

// tinygltf value → nlohmann JSON.
json from_value(const tinygltf::Value& v) {
    if (v.IsObject()) {
        json o = json::object();
        for (const auto& key : v.Keys()) o[key] = from_value(v.Get(key));
        return o;
    }
    if (v.IsArray()) {
        json a = json::array();
        for (std::size_t i = 0; i < v.ArrayLen(); ++i) a.push_back(from_value(v.Get(static_cast<int>(i))));
        return a;
    }
    if (v.IsBool()) return v.Get<bool>();
    if (v.IsInt()) return v.Get<int>();
    if (v.IsNumber()) return v.GetNumberAsDouble();
    if (v.IsString()) return v.Get<std::string>();
    return json();
}

// An object's extras: from the original JSON text when tinygltf kept it, else
// its parsed value (the file's JSON was checked by parse_json before tinygltf
// read it, so the text parses within the nesting limit).
json extras_of(const std::string& text, const tinygltf::Value& value, const std::filesystem::path& path) {
    const json j = text.empty() ? from_value(value) : parse_json(text, path.string());
    return j.is_object() ? j : json::object();
}

// nlohmann JSON → tinygltf value (for the extras we write).
tinygltf::Value to_value(const json& j) {
    if (j.is_object()) {
        tinygltf::Value::Object o;
        for (const auto& [k, v] : j.items()) o[k] = to_value(v);
        return tinygltf::Value(std::move(o));
    }
    if (j.is_array()) {
        tinygltf::Value::Array a;
        for (const auto& v : j) a.push_back(to_value(v));
        return tinygltf::Value(std::move(a));
    }
    if (j.is_boolean()) return tinygltf::Value(j.get<bool>());
    if (j.is_number_integer()) return tinygltf::Value(static_cast<int>(j.get<std::int64_t>()));
    if (j.is_number()) return tinygltf::Value(j.get<double>());
    if (j.is_string()) return tinygltf::Value(j.get<std::string>());
    return tinygltf::Value();
}

json scaled_point(const json& p, double scale) {
    if (!p.is_array()) return p;
    json out = json::array();
    for (const auto& x : p) out.push_back(x.is_number() ? json(x.get<double>() * scale) : x);
    return out;
}

BlendshapeMapping read_mapping(const json& doc, const std::filesystem::path& path);
Head read_gltf_head(const tinygltf::Model& model, const BlendshapeMapping& mapping, const std::filesystem::path& path);
tinygltf::Model load_gltf_model(const std::filesystem::path& path);

}  // namespace

std::vector<std::string> BlendshapeMapping::targets() const {
    std::set<std::string> names;
    for (const auto& [channel, row] : rows)
        for (const auto* side : {&row.both, &row.positive, &row.negative})
            for (const auto& [t, w] : *side) names.insert(t);
    return {names.begin(), names.end()};
}

std::filesystem::path default_blendshape_mapping() {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "head" / "arkit_mapping.json";
}

BlendshapeMapping read_blendshape_mapping(const std::filesystem::path& path) {
    const json doc = read_json_file(path);
    return with_json_context(path, [&] { return read_mapping(doc, path); });
}

namespace {

// The files a glTF names (buffers, images), read for tinygltf: regular files
// only (never a device or a FIFO, which could block or never end), at most
// max_resource_bytes each.
constexpr std::uintmax_t max_resource_bytes = std::uintmax_t(1) << 30;

bool read_resource(std::vector<unsigned char>* out, std::string* err, const std::string& file, void*) {
    std::error_code ec;
    const bool regular = std::filesystem::is_regular_file(file, ec);
    const auto size = regular ? std::filesystem::file_size(file, ec) : 0;
    if (!regular || ec || size > max_resource_bytes) {
        if (err) *err += (regular ? "larger than 1 GiB or unreadable: " : "not a regular file: ") + file + "\n";
        return false;
    }
    out->resize(static_cast<std::size_t>(size));
    std::ifstream in(file, std::ios::binary);
    if (!in.read(reinterpret_cast<char*>(out->data()), static_cast<std::streamsize>(size))) {
        if (err) *err += "cannot read " + file + "\n";
        return false;
    }
    return true;
}

bool resource_exists(const std::string& file, void*) {
    std::error_code ec;
    return std::filesystem::exists(file, ec);  // read_resource says why a device or folder is refused
}

std::string no_expansion(const std::string& file, void*) { return file; }

// Reads the glTF (.glb: its JSON chunk) through parse_json first, so a syntax
// error, a number out of range or nesting deeper than max_json_depth is a
// file:line:col error before tinygltf (whose JSON values and our conversion
// of them are recursive) sees it; then loads it with tinygltf.
tinygltf::Model load_gltf_model(const std::filesystem::path& path) {
    const std::string bytes = read_text_file(path);
    const bool binary = bytes.size() >= 4 && bytes.compare(0, 4, "glTF") == 0;
    if (binary) {
        // Header (magic, version, length), then the JSON chunk (length, "JSON", text).
        std::uint32_t json_bytes = 0;
        if (bytes.size() >= 20) std::memcpy(&json_bytes, bytes.data() + 12, 4);
        if (bytes.size() < 20 || bytes.compare(16, 4, "JSON") != 0 || json_bytes > bytes.size() - 20)
            throw InputError(path, "not a readable binary glTF (.glb): expected a header and a JSON chunk within the file's " +
                                       std::to_string(bytes.size()) + " bytes");
        // Positions are within the JSON chunk (line 1, column from its start).
        (void)parse_json(std::string_view(bytes).substr(20, json_bytes), path.string());
    } else {
        (void)parse_json(bytes, path.string());
    }
    if (bytes.size() > std::numeric_limits<unsigned int>::max()) throw InputError(path, "larger than 4 GiB");
    tinygltf::TinyGLTF loader;
    loader.SetStoreOriginalJSONForExtrasAndExtensions(true);
    loader.SetFsCallbacks({&resource_exists, &no_expansion, &read_resource, &tinygltf::WriteWholeFile, nullptr});
    tinygltf::Model model;
    std::string error, warning;
    const std::string base_dir = path.has_parent_path() ? path.parent_path().string() : ".";
    const bool ok =
        binary ? loader.LoadBinaryFromMemory(&model, &error, &warning, reinterpret_cast<const unsigned char*>(bytes.data()),
                                             static_cast<unsigned int>(bytes.size()), base_dir)
               : loader.LoadASCIIFromString(&model, &error, &warning, bytes.data(), static_cast<unsigned int>(bytes.size()),
                                            base_dir);
    if (!ok) throw InputError(path, "not a readable glTF 2.0 file: " + (error.empty() ? warning : error));
    return model;
}

BlendshapeMapping read_mapping(const json& doc, const std::filesystem::path& path) {
    DiagnosticList problems;
    auto problem = [&](const std::string& field, const std::string& message) {
        problems.add(path.string(), 0, 0, field, message);
    };
    if (json_string(doc, "format") != "avsi-blendshape-mapping")
        problem("format", "expected \"avsi-blendshape-mapping\", got " + doc.value("format", json()).dump());
    BlendshapeMapping m;
    m.path = path;
    const auto channels = gltf_channel_names();
    const json& rows = doc.value("parameters", json());
    if (!rows.is_object()) problem("parameters", "expected an object with one row per parameter");
    else
        for (const auto& [channel, row] : rows.items()) {
            const std::string field = "parameters." + channel;
            if (std::find(channels.begin(), channels.end(), channel) == channels.end()) {
                const auto hint = closest_match(channel, channels);
                problem(field, "expected a parameter name, \"blink\", \"tongue_tip\", \"gaze_left\" or \"gaze_up\"" +
                                   (hint.empty() ? std::string() : " (did you mean '" + hint + "'?)"));
                continue;
            }
            auto weights = [&](const json& j, const std::string& f, std::map<std::string, float>& out) {
                if (!j.is_object()) {
                    problem(f, "expected {\"<blendshape>\": weight, …}, got " + j.dump());
                    return;
                }
                for (const auto& [target, w] : j.items()) {
                    if (!w.is_number() || !std::isfinite(w.get<double>()))
                        problem(f + "." + target, "expected a number, got " + w.dump());
                    else out[target] = w.get<float>();
                }
            };
            MappingRow r;
            if (row.is_object() && (row.contains("positive") || row.contains("negative"))) {
                for (const auto& [key, value] : row.items()) {
                    if (key == "positive") weights(value, field + ".positive", r.positive);
                    else if (key == "negative") weights(value, field + ".negative", r.negative);
                    else problem(field + "." + key, "expected \"positive\" or \"negative\" (or a plain {target: weight} row)");
                }
            } else {
                weights(row, field, r.both);
            }
            m.rows[channel] = std::move(r);
        }
    problems.throw_if_any();
    return m;
}

}  // namespace

Head load_gltf_head(const std::filesystem::path& path, const std::filesystem::path& mapping_path) {
    const BlendshapeMapping mapping = read_blendshape_mapping(mapping_path);
    if (!std::filesystem::exists(path)) throw InputError(path, "cannot open: no such file");
    const tinygltf::Model model = load_gltf_model(path);
    return with_json_context(path, [&] { return read_gltf_head(model, mapping, path); });
}

namespace {

// The mesh nodes of the default scene, in order, with their world matrices.
std::vector<std::pair<int, glm::mat4>> scene_mesh_nodes(const tinygltf::Model& model, const std::filesystem::path& path) {
    std::vector<std::pair<int, glm::mat4>> mesh_nodes;
    // A node may appear once on a path from the root (the hierarchy is a tree).
    std::vector<bool> on_path(model.nodes.size(), false);
    std::size_t instances = 0;
    std::function<void(int, glm::mat4)> visit = [&](int n, glm::mat4 parent) {
        if (n < 0 || static_cast<std::size_t>(n) >= model.nodes.size())
            throw InputError(path.string(), 0, 0, "nodes", "expected a node index in [0, " + std::to_string(model.nodes.size()) +
                                                               "), got " + std::to_string(n));
        if (on_path[static_cast<std::size_t>(n)])
            throw InputError(path.string(), 0, 0, "nodes[" + std::to_string(n) + "].children",
                             "expected a tree of nodes, got node " + std::to_string(n) + " among its own descendants");
        // Shared subtrees multiply: bound the instances a small file can make.
        if (++instances > 100'000)
            throw InputError(path.string(), 0, 0, "nodes", "expected at most 100000 node instances in the scene, got more");
        on_path[static_cast<std::size_t>(n)] = true;
        const auto& node = model.nodes[static_cast<std::size_t>(n)];
        const glm::mat4 world = parent * node_matrix(node);
        if (node.mesh >= 0) mesh_nodes.emplace_back(node.mesh, world);
        for (int c : node.children) visit(c, world);
        on_path[static_cast<std::size_t>(n)] = false;
    };
    const int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (static_cast<std::size_t>(scene) < model.scenes.size())
        for (int n : model.scenes[static_cast<std::size_t>(scene)].nodes) visit(n, glm::mat4(1.0f));
    if (mesh_nodes.empty()) throw InputError(path, "the scene has no mesh");
    return mesh_nodes;
}

// What the primitives add besides the mesh: the morph targets, the one
// texture image, the materials' blend flags.
struct GltfGeometry {
    std::map<std::string, std::vector<std::pair<std::uint32_t, glm::vec3>>> targets;  // name → (vertex, offset mm)
    // Primitives of one node that share their vertex accessors share the vertices.
    std::map<std::tuple<std::size_t, int, int, int>, std::uint32_t> shared;
    std::set<std::string> target_names;
    int texture_image = -1;
    json materials = json::object();
};

// Adds primitive `pi` of mesh `mi` (node k, at `world`) to the mesh: its
// vertices (unless an earlier primitive of the node shares them), its
// triangles in its group (the material's name), its morph targets.
void add_primitive(const tinygltf::Model& model, std::size_t k, int mi, std::size_t pi, const glm::mat4& world,
                   const std::vector<std::string>& names, const std::filesystem::path& path, HeadMesh& mesh,
                   GltfGeometry& g) {
    const auto& gm = model.meshes.at(static_cast<std::size_t>(mi));
    const glm::mat3 linear(world);
    const auto& prim = gm.primitives[pi];
    if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1)
        throw InputError(path, "mesh '" + gm.name + "': only triangle primitives are supported");
    const auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) throw InputError(path, "mesh '" + gm.name + "': a primitive has no POSITION");
    const auto attribute = [&](const char* name) {
        const auto it = prim.attributes.find(name);
        return it == prim.attributes.end() ? -1 : it->second;
    };
    const auto key = std::make_tuple(k, pos_it->second, attribute("TEXCOORD_0"), attribute("COLOR_0"));
    const auto seen = g.shared.find(key);
    const bool fresh = seen == g.shared.end();
    const auto base = fresh ? static_cast<std::uint32_t>(mesh.positions.size()) : seen->second;
    if (fresh) g.shared[key] = base;
    const std::size_t count = model.accessors.at(static_cast<std::size_t>(pos_it->second)).count;
    const auto p = fresh ? read_floats(model, pos_it->second, 3, path) : std::vector<float>{};
    for (std::size_t i = 0; i < p.size() / 3; ++i)
        mesh.positions.push_back(glm::vec3(world * glm::vec4(p[3 * i], p[3 * i + 1], p[3 * i + 2], 1.0f)) * mm_per_metre);
    std::vector<float> uv, color;
    if (fresh && prim.attributes.count("TEXCOORD_0")) uv = read_floats(model, prim.attributes.at("TEXCOORD_0"), 2, path);
    if (fresh && prim.attributes.count("COLOR_0")) color = read_floats(model, prim.attributes.at("COLOR_0"), 3, path);
    glm::vec3 factor(1.0f);
    // (Appended piece by piece: GCC 12 at -O3 warns -Wrestrict,
    // wrongly, on "_" + std::to_string(…).)
    std::string group = gm.name.empty() ? std::string("mesh").append(std::to_string(k)) : gm.name;
    group.append("_").append(std::to_string(pi));
    if (prim.material >= 0) {
        const auto& mat = model.materials.at(static_cast<std::size_t>(prim.material));
        if (!mat.name.empty()) group = mat.name;
        const auto& f = mat.pbrMetallicRoughness.baseColorFactor;
        if (f.size() >= 3) factor = glm::vec3(float(f[0]), float(f[1]), float(f[2]));
        const int tex = mat.pbrMetallicRoughness.baseColorTexture.index;
        if (tex >= 0) {
            const int img = model.textures.at(static_cast<std::size_t>(tex)).source;
            if (g.texture_image >= 0 && img != g.texture_image)
                throw InputError(path, "material '" + mat.name + "': the head must use one texture image (an atlas); it uses several");
            g.texture_image = img;
        }
        if (mat.alphaMode == "BLEND") g.materials[group]["blend"] = true;
    }
    if ((!uv.empty() && uv.size() != 2 * count) || (!color.empty() && color.size() != 3 * count))
        throw InputError(path.string(), 0, 0, "meshes[" + std::to_string(mi) + "].primitives[" + std::to_string(pi) + "]",
                         "expected TEXCOORD_0 and COLOR_0 with as many elements as POSITION (" + std::to_string(count) + ")");
    for (std::size_t i = 0; fresh && i < count; ++i) {
        mesh.colors.push_back(factor * (color.empty() ? glm::vec3(1.0f)
                                                      : glm::vec3(color[3 * i], color[3 * i + 1], color[3 * i + 2])));
        mesh.uvs.push_back(uv.empty() ? glm::vec2(0.0f) : glm::vec2(uv[2 * i], 1.0f - uv[2 * i + 1]));
    }
    int gi = mesh.group_index(group);
    if (gi < 0) {
        gi = static_cast<int>(mesh.group_names.size());
        mesh.group_names.push_back(group);
    }
    std::vector<std::uint32_t> idx;
    if (prim.indices >= 0) idx = read_indices(model, prim.indices, path);
    else
        for (std::uint32_t i = 0; i < count; ++i) idx.push_back(i);
    if (idx.size() % 3 != 0) throw InputError(path, "mesh '" + gm.name + "': the index count is not a multiple of 3");
    for (std::size_t i = 0; i < idx.size(); i += 3) {
        for (int c = 0; c < 3; ++c) {
            if (idx[i + std::size_t(c)] >= count) throw InputError(path, "mesh '" + gm.name + "': a vertex index is out of range");
            mesh.indices.push_back(base + idx[i + std::size_t(c)]);
        }
        mesh.triangle_group.push_back(gi);
    }
    for (std::size_t t = 0; t < prim.targets.size(); ++t) {
        if (!fresh) {
            g.target_names.insert(t < names.size() && !names[t].empty() ? names[t] : "target_" + std::to_string(t));
            continue;
        }
        const std::string name = t < names.size() && !names[t].empty() ? names[t] : "target_" + std::to_string(t);
        g.target_names.insert(name);
        const auto it = prim.targets[t].find("POSITION");
        if (it == prim.targets[t].end()) continue;
        const auto d = read_floats(model, it->second, 3, path);
        if (d.size() != 3 * count)
            throw InputError(path.string(), 0, 0, "morph target " + name,
                             "expected as many offsets as the primitive's POSITION (" + std::to_string(count) + "), got " +
                                 std::to_string(d.size() / 3));
        auto& list = g.targets[name];
        for (std::size_t i = 0; i < d.size() / 3; ++i) {
            const glm::vec3 offset = linear * glm::vec3(d[3 * i], d[3 * i + 1], d[3 * i + 2]) * mm_per_metre;
            if (offset != glm::vec3(0.0f)) list.emplace_back(base + static_cast<std::uint32_t>(i), offset);
        }
    }
}

// Geometry, groups (material names), texture and morph targets of the mesh nodes.
GltfGeometry read_gltf_geometry(const tinygltf::Model& model, const std::vector<std::pair<int, glm::mat4>>& mesh_nodes,
                                const std::filesystem::path& path, HeadMesh& mesh) {
    GltfGeometry g;
    for (std::size_t k = 0; k < mesh_nodes.size(); ++k) {
        const auto& [mi, world] = mesh_nodes[k];
        const auto& gm = model.meshes.at(static_cast<std::size_t>(mi));
        const json mesh_extras = extras_of(gm.extras_json_string, gm.extras, path);
        std::vector<std::string> names;
        if (mesh_extras.contains("targetNames") && mesh_extras["targetNames"].is_array())
            for (const auto& t : mesh_extras["targetNames"]) names.push_back(t.is_string() ? t.get<std::string>() : "");
        for (std::size_t pi = 0; pi < gm.primitives.size(); ++pi) add_primitive(model, k, mi, pi, world, names, path, mesh, g);
    }
    if (mesh.indices.empty()) throw InputError(path, "the mesh has no triangles");
    return g;
}

// Every target the mapping needs is in the file, or an InputError lists what is missing.
void check_mapping_targets(const BlendshapeMapping& mapping, const std::set<std::string>& target_names,
                           const std::filesystem::path& path) {
    std::vector<std::string> missing;
    for (const auto& t : mapping.targets())
        if (!target_names.count(t)) missing.push_back(t);
    if (!missing.empty()) {
        std::string list, have;
        for (const auto& m : missing) list += (list.empty() ? "" : ", ") + m;
        for (const auto& h : target_names) have += (have.empty() ? "" : ", ") + h;
        throw InputError(path.string(), 0, 0, "morph targets",
                         "missing " + std::to_string(missing.size()) + " the mapping " + mapping.path.filename().string() +
                             " needs: " + list + " (the file has: " + (have.empty() ? "none" : have) + ")");
    }
}

// The texture image `image_index` as the head's RGBA texture.
void read_gltf_texture(const tinygltf::Model& model, int image_index, const std::filesystem::path& path, Head& head) {
    const auto& img = model.images.at(static_cast<std::size_t>(image_index));
    if (img.image.empty() || img.width <= 0 || img.height <= 0 || (img.component != 3 && img.component != 4) ||
        img.image.size() < std::size_t(img.width) * std::size_t(img.height) * std::size_t(img.component))
        throw InputError(path, "the texture image could not be decoded");
    ImageRgba tex;
    tex.width = img.width;
    tex.height = img.height;
    tex.rgba.resize(std::size_t(img.width) * std::size_t(img.height) * 4);
    const auto comp = static_cast<std::size_t>(img.component);
    for (std::size_t i = 0; i < tex.rgba.size() / 4; ++i) {
        for (std::size_t c = 0; c < 3; ++c) tex.rgba[4 * i + c] = img.image[i * comp + c];
        tex.rgba[4 * i + 3] = comp == 4 ? img.image[i * comp + 3] : 255;
    }
    head.texture = std::move(tex);
    head.texture_path = path;
}

// The rig document: the extras' sections (metres → mm) and one blendshape
// transform per mapping row, side and target.
json gltf_rig_document(const json& avsi, json materials, const BlendshapeMapping& mapping,
                       std::map<std::string, std::vector<std::pair<std::uint32_t, glm::vec3>>>& targets) {
    json doc = json::object();
    if (avsi.contains("landmarks") && avsi["landmarks"].is_object()) {
        json lm = json::object();
        for (const auto& [key, value] : avsi["landmarks"].items())
            lm[key] = value.is_number() ? json(value.get<double>() * mm_per_metre) : scaled_point(value, mm_per_metre);
        doc["landmarks"] = lm;
    }
    for (const char* key : {"articulation", "lip_contact"})
        if (avsi.contains(key)) doc[key] = avsi[key];
    if (avsi.contains("materials") && avsi["materials"].is_object())
        for (const auto& [g, m] : avsi["materials"].items()) materials[g] = m;
    if (!materials.empty()) doc["materials"] = materials;
    json transforms = json::array();
    for (const auto& mapping_row : mapping.rows) {
        const std::string& channel = mapping_row.first;  // not a structured binding: lambdas below capture it (clang 14)
        const MappingRow& row = mapping_row.second;
        const auto [lo, hi] = channel_range(channel);
        auto add = [&](const std::map<std::string, float>& weights, double per_unit, const char* side) {
            for (const auto& [target, w] : weights) {
                json vertices = json::array(), offsets = json::array();
                for (const auto& [v, d] : targets[target]) {
                    vertices.push_back(v);
                    for (int c = 0; c < 3; ++c) offsets.push_back(double(d[c]) * w * per_unit);
                }
                json t = {{"channel", channel}, {"note", target}, {"blendshape", {{"vertices", vertices}, {"offsets", offsets}}}};
                if (side) t["side"] = side;
                transforms.push_back(t);
            }
        };
        add(row.both, 1.0, nullptr);
        add(row.positive, 1.0 / hi, "positive");
        if (lo < 0) add(row.negative, 1.0 / lo, "negative");
    }
    doc["transforms"] = transforms;
    return doc;
}

Head read_gltf_head(const tinygltf::Model& model, const BlendshapeMapping& mapping, const std::filesystem::path& path) {
    Head head;
    head.obj_path = path;
    head.rig_path = path;
    const json avsi = extras_of(model.extras_json_string, model.extras, path).value("avsi", json::object());
    if (!avsi.is_object())
        throw InputError(path.string(), 0, 0, "extras.avsi",
                         "expected an object of landmarks, articulation, lip_contact and materials, got " + avsi.dump().substr(0, 40));
    GltfGeometry g = read_gltf_geometry(model, scene_mesh_nodes(model, path), path, head.mesh);
    check_mapping_targets(mapping, g.target_names, path);
    if (g.texture_image >= 0) read_gltf_texture(model, g.texture_image, path, head);
    else head.mesh.uvs.clear();
    detail::read_rig(head, gltf_rig_document(avsi, g.materials, mapping, g.targets), std::nullopt, false);
    return head;
}

}  // namespace

namespace {

// Each target's shape: the rig posed at its row's end, split at the midline
// for an _L/_R pair; a target named by two rows is refused.
std::map<std::string, std::vector<glm::vec3>> target_shapes(const Head& head, const BlendshapeMapping& mapping) {
    const auto& mesh = head.mesh;
    const std::size_t n = mesh.positions.size();
    std::map<std::string, std::vector<glm::vec3>> shapes;
    std::map<std::string, std::string> owner;
    // The shapes without the lip contact step: the loaded head applies it
    // after blending them (the extras carry it), as the rig does.
    Head bare;
    bare.mesh.positions = mesh.positions;
    bare.transforms = head.transforms;
    std::vector<glm::vec3> rest;
    pose_positions(bare, Pose{}, rest);
    for (const auto& mapping_row : mapping.rows) {
        const std::string& channel = mapping_row.first;  // not a structured binding: lambdas below capture it (clang 14)
        const MappingRow& row = mapping_row.second;
        const auto [lo, hi] = channel_range(channel);
        auto side_shapes = [&](const std::map<std::string, float>& weights, double value) {
            if (weights.empty()) return;
            Pose pose;
            if (const auto p = synth::param_from_name(channel)) pose.params[synth::index(*p)] = value;
            else if (channel == "blink") pose.blink = value;
            else if (channel == "gaze_left") pose.gaze_left = value;
            else if (channel == "gaze_up") pose.gaze_up = value;
            else pose.tongue_tip = value;
            std::vector<glm::vec3> posed;
            pose_positions(bare, pose, posed);
            for (std::size_t i = 0; i < n; ++i) posed[i] -= rest[i];
            // An _L/_R pair shares the shape across the midline (the speaker's left is +x).
            std::vector<std::string> names;
            for (const auto& [t, w] : weights) names.push_back(t);
            auto ends = [](const std::string& t, const char* suffix) { return t.size() > 2 && t.substr(t.size() - 2) == suffix; };
            const bool pair = names.size() == 2 && ((ends(names[0], "_L") && ends(names[1], "_R")) ||
                                                    (ends(names[0], "_R") && ends(names[1], "_L")));
            for (const auto& [t, w] : weights) {
                const std::string where = channel + (value > 0 ? " positive" : value < 0 ? " negative" : "");
                if (!owner.emplace(t, where).second)
                    throw InputError(mapping.path.string(), 0, 0, "parameters." + channel,
                                     "target " + t + " is also driven by " + owner[t] + ": an exported target can hold one shape");
                if (w == 0.0f) throw InputError(mapping.path.string(), 0, 0, "parameters." + channel + "." + t, "a zero weight cannot be exported");
                std::vector<glm::vec3> d(n);
                const bool left = t.size() > 2 && t.substr(t.size() - 2) == "_L";
                for (std::size_t i = 0; i < n; ++i) {
                    float share = 1.0f;
                    if (pair) {
                        const float l = smoothstep(-5.0f, 5.0f, mesh.positions[i].x);
                        share = left ? l : 1.0f - l;
                    } else {
                        share = 1.0f / float(weights.size());
                    }
                    d[i] = posed[i] * (share / w);
                }
                shapes[t] = std::move(d);
            }
        };
        side_shapes(row.both, 1.0);
        side_shapes(row.positive, hi);
        if (lo < 0) side_shapes(row.negative, lo);
    }

    return shapes;
}

// A glTF model being written: one buffer, a view per appended block, and accessors on them.
struct GltfWriter {
    tinygltf::Model model;
    tinygltf::Buffer buffer;

    // Appends bytes (4-byte aligned) as a new buffer view; returns its index.
    int append(const void* data, std::size_t bytes) {
        while (buffer.data.size() % 4) buffer.data.push_back(0);
        const std::size_t offset = buffer.data.size();
        const auto* p = static_cast<const unsigned char*>(data);
        buffer.data.insert(buffer.data.end(), p, p + bytes);
        tinygltf::BufferView view;
        view.buffer = 0;
        view.byteOffset = offset;
        view.byteLength = bytes;
        model.bufferViews.push_back(view);
        return static_cast<int>(model.bufferViews.size() - 1);
    }
    // An accessor on a view; returns its index.
    int accessor(int view, int component, int type, std::size_t count, std::vector<double> min = {},
                 std::vector<double> max = {}) {
        tinygltf::Accessor a;
        a.bufferView = view;
        a.componentType = component;
        a.type = type;
        a.count = count;
        a.minValues = std::move(min);
        a.maxValues = std::move(max);
        model.accessors.push_back(a);
        return static_cast<int>(model.accessors.size() - 1);
    }
};

// The accessors every primitive shares, so vertex indices stay the head's.
struct VertexAccessors {
    int position = -1, normal = -1, color = -1, uv = -1;  // uv -1: untextured
    bool textured = false;
};

// Positions (metres, with their bounds), normals, colours and, for a
// textured head, texture coordinates.
VertexAccessors add_vertex_accessors(GltfWriter& w, const Head& head) {
    const auto& mesh = head.mesh;
    const std::size_t n = mesh.positions.size();
    std::vector<float> pos(3 * n), nrm(3 * n), uv(2 * n), col(3 * n);
    std::vector<glm::vec3> normals;
    compute_normals(mesh.positions, mesh.indices, normals);
    std::vector<double> lo(3, 1e30), hi(3, -1e30);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            pos[3 * i + std::size_t(c)] = mesh.positions[i][c] / mm_per_metre;
            lo[std::size_t(c)] = std::min(lo[std::size_t(c)], double(pos[3 * i + std::size_t(c)]));
            hi[std::size_t(c)] = std::max(hi[std::size_t(c)], double(pos[3 * i + std::size_t(c)]));
            nrm[3 * i + std::size_t(c)] = normals[i][c];
            col[3 * i + std::size_t(c)] = mesh.colors[i][c];
        }
    VertexAccessors a;
    a.textured = head.texture.has_value() && mesh.uvs.size() == n;
    for (std::size_t i = 0; i < n && a.textured; ++i) uv[2 * i] = mesh.uvs[i].x, uv[2 * i + 1] = 1.0f - mesh.uvs[i].y;
    a.position = w.accessor(w.append(pos.data(), pos.size() * 4), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n, lo, hi);
    a.normal = w.accessor(w.append(nrm.data(), nrm.size() * 4), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
    a.color = w.accessor(w.append(col.data(), col.size() * 4), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
    if (a.textured)
        a.uv = w.accessor(w.append(uv.data(), uv.size() * 4), TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, n);
    return a;
}

// One displacement accessor (metres, with its bounds) per target, by name.
std::vector<std::pair<std::string, int>> add_target_accessors(GltfWriter& w,
                                                              const std::map<std::string, std::vector<glm::vec3>>& shapes,
                                                              std::size_t n) {
    std::vector<std::pair<std::string, int>> target_accessors;
    for (const auto& [name, d] : shapes) {
        std::vector<float> data(3 * n);
        std::vector<double> tlo(3, 1e30), thi(3, -1e30);
        for (std::size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) {
                data[3 * i + std::size_t(c)] = d[i][c] / mm_per_metre;
                tlo[std::size_t(c)] = std::min(tlo[std::size_t(c)], double(data[3 * i + std::size_t(c)]));
                thi[std::size_t(c)] = std::max(thi[std::size_t(c)], double(data[3 * i + std::size_t(c)]));
            }
        target_accessors.emplace_back(name, w.accessor(w.append(data.data(), data.size() * 4), TINYGLTF_COMPONENT_TYPE_FLOAT,
                                                       TINYGLTF_TYPE_VEC3, n, tlo, thi));
    }
    return target_accessors;
}

// The head's texture PNG embedded as image 0, with its texture and sampler.
void add_texture(GltfWriter& w, const Head& head, const std::filesystem::path& out_path) {
    std::string png;
    if (!head.texture_path.empty() && head.texture_path.extension() == ".png") png = read_text_file(head.texture_path);
    if (png.empty()) throw InputError(out_path, "the head's texture is not a PNG file that can be embedded");
    tinygltf::Image image;
    image.bufferView = w.append(png.data(), png.size());
    image.mimeType = "image/png";
    image.name = "texture";
    w.model.images.push_back(image);
    tinygltf::Texture texture;
    texture.source = 0;
    tinygltf::Sampler sampler;
    sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
    w.model.samplers.push_back(sampler);
    texture.sampler = 0;
    w.model.textures.push_back(texture);
}

// The mesh (one primitive and material per group, every target on each)
// under the scene's one node.
void add_head_mesh(GltfWriter& w, const Head& head, const VertexAccessors& va,
                   const std::vector<std::pair<std::string, int>>& target_accessors) {
    const auto& mesh = head.mesh;
    tinygltf::Mesh gm;
    gm.name = "head";
    tinygltf::Value::Array names;
    for (const auto& [name, a] : target_accessors) names.emplace_back(name);
    tinygltf::Value::Object mesh_extras;
    mesh_extras["targetNames"] = tinygltf::Value(names);
    gm.extras = tinygltf::Value(mesh_extras);
    for (std::size_t g = 0; g < mesh.group_names.size(); ++g) {
        std::vector<std::uint32_t> idx;
        for (std::size_t t = 0; t < mesh.triangle_group.size(); ++t)
            if (mesh.triangle_group[t] == int(g)) idx.insert(idx.end(), &mesh.indices[3 * t], &mesh.indices[3 * t] + 3);
        if (idx.empty()) continue;
        tinygltf::Material mat;
        mat.name = mesh.group_names[g];
        mat.pbrMetallicRoughness.metallicFactor = 0.0;
        mat.pbrMetallicRoughness.roughnessFactor = 0.6;
        if (va.textured) mat.pbrMetallicRoughness.baseColorTexture.index = 0;
        if (head.materials.at(g).blend) mat.alphaMode = "BLEND", mat.doubleSided = true;
        w.model.materials.push_back(mat);
        tinygltf::Primitive prim;
        prim.mode = TINYGLTF_MODE_TRIANGLES;
        prim.material = static_cast<int>(w.model.materials.size() - 1);
        prim.indices = w.accessor(w.append(idx.data(), idx.size() * 4), TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                  TINYGLTF_TYPE_SCALAR, idx.size());
        prim.attributes["POSITION"] = va.position;
        prim.attributes["NORMAL"] = va.normal;
        prim.attributes["COLOR_0"] = va.color;
        if (va.uv >= 0) prim.attributes["TEXCOORD_0"] = va.uv;
        for (const auto& [name, a] : target_accessors) prim.targets.push_back({{"POSITION", a}});
        gm.primitives.push_back(prim);
    }
    gm.weights.assign(target_accessors.size(), 0.0);
    w.model.meshes.push_back(gm);
    tinygltf::Node node;
    node.mesh = 0;
    node.name = "head";
    w.model.nodes.push_back(node);
    tinygltf::Scene scene;
    scene.nodes = {0};
    w.model.scenes.push_back(scene);
    w.model.defaultScene = 0;
}

// The avsi extras: landmarks (metres), articulation, lip contact, materials.
json avsi_extras(const Head& head) {
    const auto& L = head.landmarks;
    auto point = [](glm::vec3 p) { return json::array({p.x / mm_per_metre, p.y / mm_per_metre, p.z / mm_per_metre}); };
    json avsi;
    avsi["landmarks"] = {{"left_eye", point(L.left_eye)},         {"right_eye", point(L.right_eye)},
                         {"nose_bottom", point(L.nose_bottom)},   {"mouth_left", point(L.mouth_left)},
                         {"mouth_right", point(L.mouth_right)},   {"mouth_middle", point(L.mouth_middle)},
                         {"head_center", point(L.head_center)},   {"iris_diameter", L.iris_diameter / mm_per_metre},
                         {"head_height", L.head_height / mm_per_metre}};
    if (L.has_neck_pivot) avsi["landmarks"]["neck_pivot"] = point(L.neck_pivot);
    if (head.articulation) {
        const auto& a = *head.articulation;
        avsi["articulation"] = {{"upper_lip_contour", a.upper_lip_contour},
                                {"lower_lip_contour", a.lower_lip_contour},
                                {"mouth_corners", {a.mouth_corner_left, a.mouth_corner_right}},
                                {"upper_lip_point", a.upper_lip_point},
                                {"lower_lip_point", a.lower_lip_point},
                                {"upper_incisor_edge", a.upper_incisor_edge},
                                {"lower_incisor_edge", a.lower_incisor_edge},
                                {"lower_lip_surface", a.lower_lip_surface},
                                {"up", {a.up.x, a.up.y, a.up.z}},
                                {"forward", {a.forward.x, a.forward.y, a.forward.z}}};
    }
    // The rig file's lip contact and materials, as written (group names are the materials').
    if (!head.rig_path.empty() && head.rig_path.extension() == ".json") {
        const json rig = read_json_file(head.rig_path);
        for (const char* key : {"lip_contact", "materials"})
            if (rig.contains(key)) avsi[key] = rig[key];
    }
    return avsi;
}

}  // namespace

void export_gltf_head(const Head& head, const std::filesystem::path& out_path, const std::filesystem::path& mapping_path) {
    const BlendshapeMapping mapping = read_blendshape_mapping(mapping_path);
    const auto shapes = target_shapes(head, mapping);
    // Buffers: positions, normals, texture coordinates, colours, per target
    // a displacement, the texture PNG, then per group an index list.
    GltfWriter w;
    w.model.asset.version = "2.0";
    w.model.asset.generator = "avsi export-head";
    const VertexAccessors va = add_vertex_accessors(w, head);
    const auto target_accessors = add_target_accessors(w, shapes, head.mesh.positions.size());
    if (va.textured) add_texture(w, head, out_path);
    add_head_mesh(w, head, va, target_accessors);
    w.model.buffers.push_back(w.buffer);
    tinygltf::Value::Object asset_extras;
    asset_extras["avsi"] = to_value(avsi_extras(head));
    w.model.extras = tinygltf::Value(asset_extras);

    if (out_path.has_parent_path()) std::filesystem::create_directories(out_path.parent_path());
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToFile(&w.model, out_path.string(), false, true, false, out_path.extension() == ".glb"))
        throw InputError(out_path, "cannot write the glTF file");
}

}  // namespace avsi::stimuli
