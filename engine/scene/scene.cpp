#include "scene/scene.h"

#include "scene/json_reader.h"

#include <glm/geometric.hpp>

#include <fstream>
#include <limits>
#include <sstream>

namespace fulgur::scene {

using detail::JsonObject;
using detail::Range;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void parse_medium(JsonObject o, transport::Medium& m) {
    // kappa up to 10 1/m: a 1 m voxel at density 1 is then optically 10 deep; anything
    // denser is a unit mistake (1/km vs 1/m) rather than a cloud.
    m.extinction = o.number("extinction", Range{0.0, 10.0, true, false});
    m.albedo = o.number_or("albedo", m.albedo, Range{0.0, 1.0});
    // |g| = 1 is a delta phase function; transport clamps at kMaxAbsG, the file must not ask for it.
    m.g = o.number_or("g", m.g, Range{-1.0, 1.0, true, true});
    o.finish();
}

void parse_generator(JsonObject o, cloud::CumulonimbusParams& p) {
    p.seed = o.seed_or("seed", p.seed);
    p.grid = o.int3_or("grid", p.grid, 1, 1024);
    p.voxel_size = o.number_or("voxel_size", p.voxel_size, Range{0.0, 10000.0, true, false});
    p.base_height = o.number_or("base_height", p.base_height, Range{0.0, 50000.0});
    p.top_height = o.number_or("top_height", p.top_height, Range{0.0, 50000.0, true, false});
    p.tower_radius = o.number_or("tower_radius", p.tower_radius, Range{0.0, 1e6, true, false});
    p.anvil = o.boolean_or("anvil", p.anvil);
    p.anvil_radius = o.number_or("anvil_radius", p.anvil_radius, Range{0.0, 1e6, true, false});
    p.anvil_thickness = o.number_or("anvil_thickness", p.anvil_thickness, Range{0.0, 50000.0, true, false});
    p.cells = int(o.integer_or("cells", p.cells, 1, 1000));
    p.steps = int(o.integer_or("steps", p.steps, 1, 1000));
    p.p_ext = o.number_or("p_ext", p.p_ext, Range{0.0, 1.0});
    p.p_hum = o.number_or("p_hum", p.p_hum, Range{0.0, 1.0});
    p.p_act = o.number_or("p_act", p.p_act, Range{0.0, 1.0});
    p.average_steps = int(o.integer_or("average_steps", p.average_steps, 1, 100));
    p.smoothing_radius = int(o.integer_or("smoothing_radius", p.smoothing_radius, 0, 16));
    o.finish();
    if (!(p.base_height < p.top_height))
        o.fail("top_height", "must be above base_height (" + std::to_string(p.base_height) + " m)");
}

void parse_cloud(JsonObject o, CloudSource& c, const std::filesystem::path& base_dir) {
    const bool has_gen = o.has("generator"), has_file = o.has("file");
    if (has_gen == has_file) o.fail("generator", "give exactly one of \"generator\" (an object) or \"file\" (a NRRD path)");
    if (has_gen) {
        c.kind = CloudSource::Kind::Generator;
        parse_generator(o.object("generator"), c.generator);
    } else {
        c.kind = CloudSource::Kind::File;
        const std::filesystem::path f = o.string("file");
        c.file = f.is_absolute() ? f : base_dir / f;
    }
    o.finish();
}

void parse_transport(JsonObject o, TransportSettings& t) {
    const std::string solver = o.choice_or("solver", "lattice_boltzmann", {"lattice_boltzmann", "monte_carlo"});
    t.solver = solver == "monte_carlo" ? TransportSettings::Solver::MonteCarlo : TransportSettings::Solver::LatticeBoltzmann;
    if (auto lb = o.optional_object("lattice_boltzmann")) {
        t.lb_collision = lb->choice_or("collision", t.lb_collision, {"corrected", "published"});
        t.lb_absorption = lb->choice_or("absorption", t.lb_absorption, {"physical", "conservative"});
        t.lb_tolerance = lb->number_or("tolerance", t.lb_tolerance, Range{0.0, 0.1, true, false});
        t.lb_max_iterations = int(lb->integer_or("max_iterations", t.lb_max_iterations, 1, 1'000'000));
        lb->finish();
    }
    if (auto mc = o.optional_object("monte_carlo")) {
        t.mc_paths = std::uint64_t(mc->integer_or("paths", std::int64_t(t.mc_paths), 1000, std::int64_t(1) << 40));
        t.mc_seed = mc->seed_or("seed", t.mc_seed);
        t.mc_batches = int(mc->integer_or("batches", t.mc_batches, 2, 1024));
        mc->finish();
    }
    o.finish();
}

void parse_virtual_lights(JsonObject o, basis::VirtualLightParams& v) {
    v.h_usr = o.number_or("h_usr", v.h_usr, Range{0.0, 1e6, true, false});
    // 1/m^2. Any epsilon >= 1/h_usr^2 already puts the layer after the first one on the
    // ground; the upper bound only rejects nonsense.
    v.epsilon = o.number_or("epsilon", v.epsilon, Range{0.0, 1e6});
    v.margin = o.number_or("margin", v.margin, Range{0.0, 1e6});
    v.ground_height = o.number_or("ground_height", v.ground_height, Range{-1e6, 1e6});
    v.density_threshold = o.number_or("density_threshold", v.density_threshold, Range{0.0, 1.0, false, true});
    o.finish();
    basis::validate(v, o.file() + ": virtual_lights");
}

void parse_compression(JsonObject o, basis::CompressionParams& c) {
    const std::string mode = o.choice_or("threshold", std::string(basis::to_string(c.mode)),
                                         {"absolute", "relative_l2", "energy"});
    c.mode = mode == "absolute"      ? basis::ThresholdMode::Absolute
             : mode == "relative_l2" ? basis::ThresholdMode::RelativeL2
                                     : basis::ThresholdMode::Energy;
    if (c.mode == basis::ThresholdMode::Energy)
        c.xi = o.number_or("xi", c.xi, Range{0.0, 1.0});  // fraction of each basis' energy kept
    else if (o.has("xi"))
        c.xi = o.number("xi", Range{0.0, 1e30});  // absolute: units of S; relative_l2: fraction of ||B||
    else
        o.fail("xi", std::string("required with threshold \"") + mode + "\" (the default xi belongs to \"energy\")");
    const std::string prec = o.choice_or("precision", std::string(basis::to_string(c.precision)), {"float32", "float16"});
    c.precision = prec == "float32" ? basis::Precision::Float32 : basis::Precision::Float16;
    const std::string dec = o.choice_or("decomposition", std::string(basis::to_string(c.decomposition)),
                                        {"nonstandard", "standard"});
    c.decomposition = dec == "standard" ? basis::Decomposition::Standard : basis::Decomposition::NonStandard;
    o.finish();
    basis::validate(c, o.file() + ": compression");
}

void parse_lights(JsonObject& root, Scene& s) {
    for (JsonObject& l : root.objects("lights")) {
        const std::string type = l.choice_or("type", "", {"point", "sun"});
        if (type.empty()) l.fail("type", "required: \"point\" or \"sun\"");
        if (type == "point") {
            PointLight p;
            p.position = l.vec3("position", Range{-1e7, 1e7});
            p.intensity = l.number_or("intensity", p.intensity, Range{0.0, kInf, false, true});
            s.point_lights.push_back(p);
        } else {
            if (s.sun) l.fail("type", "a scene has at most one sun");
            SunLight sun;
            const glm::dvec3 d = l.vec3("direction", Range{-1e6, 1e6});
            if (glm::length(d) < 1e-9) l.fail("direction", "must be a non-zero vector");
            sun.direction = glm::normalize(d);
            sun.irradiance = l.number_or("irradiance", sun.irradiance, Range{0.0, kInf, false, true});
            s.sun = sun;
        }
        l.finish();
    }
}

void parse_effects(JsonObject o, Effects& e) {
    e.lightning = o.boolean_or("lightning", e.lightning);
    e.single_scattering = o.boolean_or("single_scattering", e.single_scattering);
    e.multiple_scattering = o.boolean_or("multiple_scattering", e.multiple_scattering);
    e.sun = o.boolean_or("sun", e.sun);
    e.glow = o.boolean_or("glow", e.glow);
    e.ground = o.boolean_or("ground", e.ground);
    o.finish();
}

}  // namespace

Scene parse_scene(std::string_view json_text, std::string_view file_name, const std::filesystem::path& base_dir) {
    const std::string file(file_name);
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(json_text);
    } catch (const nlohmann::json::parse_error& e) {
        // e.byte is the 1-based position of the offending character.
        throw core::Error(file + " (byte " + std::to_string(e.byte) + ")", std::string("invalid JSON: ") + e.what());
    }
    JsonObject root(j, file, "");
    Scene s;
    const auto version = root.integer("fulgur_scene", 1, 1000);
    if (version != kFormatVersion)
        root.fail("fulgur_scene", "format version " + std::to_string(version) + " is not supported (this build reads " +
                                      std::to_string(kFormatVersion) + ")");
    s.name = root.string_or("name", "");
    parse_medium(root.object("medium"), s.medium);
    parse_cloud(root.object("cloud"), s.cloud, base_dir);
    if (auto lighting = root.optional_object("lighting")) {
        s.lighting_downsample = int(lighting->integer_or("downsample", s.lighting_downsample, 1, 64));
        s.directions = int(lighting->integer_or("directions", s.directions, 1, 26));
        if (s.directions != 1 && s.directions != 6 && s.directions != 18 && s.directions != 26)
            lighting->fail("directions", "must be 1, 6, 18 or 26, got " + std::to_string(s.directions));
        lighting->finish();
    }
    if (auto t = root.optional_object("transport")) parse_transport(*t, s.transport);
    if (auto v = root.optional_object("virtual_lights")) parse_virtual_lights(*v, s.virtual_lights);
    if (auto c = root.optional_object("compression")) parse_compression(*c, s.compression);
    parse_lights(root, s);
    if (auto e = root.optional_object("effects")) parse_effects(*e, s.effects);
    root.finish();
    if (s.effects.sun && !s.sun) root.fail("effects", "\"sun\": true needs a light of type \"sun\" in \"lights\"");
    return s;
}

Scene load_scene(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw core::Error(path.string(), "cannot open scene file");
    std::ostringstream text;
    text << in.rdbuf();
    Scene s = parse_scene(text.str(), path.string(), path.parent_path());
    s.path = path;
    return s;
}

core::Grid3<float> make_density(const Scene& s) {
    if (s.cloud.kind == CloudSource::Kind::File) return cloud::load_density(s.cloud.file);
    return cloud::generate_cumulonimbus(s.cloud.generator);
}

transport::LightingMedium make_lighting_medium(const Scene& s, const core::Grid3<float>& density) {
    transport::LightingMedium m;
    m.density = core::downsample(density, s.lighting_downsample);
    m.optics = s.medium;
    return m;
}

}  // namespace fulgur::scene
