#include "scene/scene.h"

#include "scene/detail/json_reader.h"

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>

namespace fulgur::scene {

using detail::JsonObject;
using detail::Range;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Runs another module's validator, whose errors name a dotted field ("lightning.timing.x"),
// and rethrows them naming the file and the field as a JSON pointer ("/lightning/timing/x").
template <class F>
void validated_as_pointer(const std::string& file, F&& validate) {
    try {
        validate();
    } catch (const core::Error& e) {
        throw core::Error(file + ": " + detail::dotted_to_pointer(e.where()), e.reason());
    }
}

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
    // Ranges here are what each field can ever mean; validate_cumulonimbus() then checks
    // that the fields agree with each other and that the cloud fits in its grid.
    constexpr double kMaxLength = 1e6;  // metres: far beyond any storm, catches unit mistakes
    p.seed = o.seed_or("seed", p.seed);
    p.grid = o.int3_or("grid", p.grid, 8, 1024);
    p.voxel_size = o.number_or("voxel_size", p.voxel_size, Range{0.0, 10000.0, true, false});
    p.base_height = o.number_or("base_height", p.base_height, Range{0.0, 50000.0});
    p.top_height = o.number_or("top_height", p.top_height, Range{0.0, 50000.0, true, false});
    p.tower_radius = o.number_or("tower_radius", p.tower_radius, Range{0.0, kMaxLength, true, false});
    p.cells = int(o.integer_or("cells", p.cells, 0, 1000));
    p.shear = o.number_or("shear", p.shear, Range{-kMaxLength, kMaxLength});
    p.flanking_towers = int(o.integer_or("flanking_towers", p.flanking_towers, 0, 8));
    p.anvil = o.boolean_or("anvil", p.anvil);
    p.anvil_radius = o.number_or("anvil_radius", p.anvil_radius, Range{0.0, kMaxLength, true, false});
    p.anvil_thickness = o.number_or("anvil_thickness", p.anvil_thickness, Range{0.0, 50000.0, true, false});
    p.anvil_offset = o.number_or("anvil_offset", p.anvil_offset, Range{0.0, kMaxLength});
    p.overshoot = o.number_or("overshoot", p.overshoot, Range{0.0, 50000.0});
    p.edge_softness = o.number_or("edge_softness", p.edge_softness, Range{0.0, 1.0, true, false});
    p.steps = int(o.integer_or("steps", p.steps, 1, 1000));
    p.p_ext = o.number_or("p_ext", p.p_ext, Range{0.0, 1.0});
    p.p_hum = o.number_or("p_hum", p.p_hum, Range{0.0, 1.0, true, false});
    p.p_act = o.number_or("p_act", p.p_act, Range{0.0, 1.0, true, false});
    p.average_steps = int(o.integer_or("average_steps", p.average_steps, 1, 255));
    p.smoothing_radius = int(o.integer_or("smoothing_radius", p.smoothing_radius, 0, 16));
    p.density_gain = o.number_or("density_gain", p.density_gain, Range{0.0, 100.0, true, false});
    o.finish();
    // e.where() is the dotted field path ("cloud.generator.top_height").
    validated_as_pointer(o.file(), [&] { cloud::validate_cumulonimbus(p); });
}

// "cloud": {"vdb": "file.vdb", ...}: the options of cloud::VdbImport by the same names.
void parse_vdb(JsonObject& o, CloudSource& c) {
    cloud::VdbImport& v = c.vdb;
    if (o.has("grid")) {
        v.grid = o.string("grid");
        if (v.grid.empty()) o.fail("grid", "must name a grid (leave it out for the file's first float grid)");
    }
    if (o.has("scale") && o.has("voxel_size"))
        o.fail("voxel_size",
               "give at most one of \"scale\" (metres per file unit) and \"voxel_size\" (metres per file voxel)");
    const Range length{core::kMinVoxelSize, core::kMaxVoxelSize};
    v.scale = o.number_or("scale", v.scale, Range{0.0, 1e9, true, false});
    v.voxel_size = o.number_or("voxel_size", 0.0, length);
    v.density_voxel_size = o.number_or("density_voxel_size", 0.0, length);
    v.density_scale = o.number_or("density_scale", v.density_scale, Range{0.0, 1e9, true, false});
    v.y_up = o.choice_or("up", "z", {"z", "y"}) == "y";
    v.offset = o.vec3_or("offset", v.offset, Range{-core::kMaxOrigin / 10.0, core::kMaxOrigin / 10.0});
}

// "cloud": {"detail": {...}}: cloud::SubvoxelDetail by the same names.
cloud::SubvoxelDetail parse_detail(JsonObject o) {
    cloud::SubvoxelDetail d;
    d.seed = o.seed_or("seed", d.seed);
    d.scale = o.number_or("scale", d.scale, Range{1.0, 1e5});
    d.octaves = int(o.integer_or("octaves", d.octaves, 1, cloud::kMaxDetailOctaves));
    d.strength = o.number_or("strength", d.strength, Range{0.0, 1.0});
    o.finish();
    validated_as_pointer(o.file(), [&] { cloud::validate_subvoxel_detail(d); });
    return d;
}

// "rain": cloud::RainParams by the same names.
cloud::RainParams parse_rain(JsonObject o) {
    cloud::RainParams p;
    p.rate = o.number_or("rate", p.rate, Range{0.0, 1000.0, true, false});
    p.threshold = o.number_or("threshold", p.threshold, Range{0.0, 1.0, false, true});
    p.shear = o.vec2_or("shear", p.shear, Range{-5000.0, 5000.0});
    p.streak_scale = o.number_or("streak_scale", p.streak_scale, Range{1.0, 1e5});
    p.streak_strength = o.number_or("streak_strength", p.streak_strength, Range{0.0, 1.0});
    p.seed = o.seed_or("seed", p.seed);
    p.g = o.number_or("g", p.g, Range{-1.0, 1.0, true, true});
    p.albedo = o.number_or("albedo", p.albedo, Range{0.0, 1.0});
    o.finish();
    validated_as_pointer(o.file(), [&] { cloud::validate_rain(p); });
    return p;
}

void parse_cloud(JsonObject o, CloudSource& c, const std::filesystem::path& base_dir) {
    const int sources = int(o.has("generator")) + int(o.has("file")) + int(o.has("vdb"));
    if (sources != 1)
        o.fail("generator",
               "give exactly one of \"generator\" (an object), \"file\" (a NRRD path) or \"vdb\" (an OpenVDB path)");
    auto path = [&](std::string_view key) {
        const std::filesystem::path f = o.string(key);
        return f.is_absolute() ? f : base_dir / f;
    };
    if (o.has("generator")) {
        c.kind = CloudSource::Kind::Generator;
        parse_generator(o.object("generator"), c.generator);
    } else if (o.has("file")) {
        c.kind = CloudSource::Kind::File;
        c.file = path("file");
    } else {
        c.kind = CloudSource::Kind::Vdb;
        c.file = path("vdb");
        parse_vdb(o, c);
    }
    if (auto d = o.optional_object("detail")) c.detail = parse_detail(*d);
    o.finish();
}

void parse_transport(JsonObject o, TransportSettings& t) {
    const std::string solver = o.choice_or("solver", "lattice_boltzmann", {"lattice_boltzmann", "monte_carlo"});
    t.solver =
        solver == "monte_carlo" ? TransportSettings::Solver::MonteCarlo : TransportSettings::Solver::LatticeBoltzmann;
    if (auto lb = o.optional_object("lattice_boltzmann")) {
        t.lb_collision = lb->choice_or("collision", t.lb_collision, {"corrected", "published"});
        t.lb_absorption = lb->choice_or("absorption", t.lb_absorption, {"physical", "conservative"});
        t.lb_thick_voxels = lb->choice_or("thick_voxels", t.lb_thick_voxels, {"saturate", "diffusion_matched"});
        t.lb_tolerance = lb->number_or("tolerance", t.lb_tolerance, Range{0.0, 0.1, true, false});
        t.lb_max_iterations = int(lb->integer_or("max_iterations", t.lb_max_iterations, 1, 1'000'000));
        t.lb_exact_orders = int(lb->integer_or("exact_orders", t.lb_exact_orders, 1, 2));
        t.lb_order2_paths =
            std::uint64_t(lb->integer_or("order2_paths", std::int64_t(t.lb_order2_paths), 1000, std::int64_t(1) << 32));
        lb->finish();
    }
    t.refine = int(o.integer_or("refine", t.refine, 1, 64));
    if (auto st = o.optional_object("static_light")) {
        t.static_refine = int(st->integer_or("refine", t.static_refine, 0, 64));
        t.static_exact_orders = int(st->integer_or("exact_orders", t.static_exact_orders, 0, 2));
        t.static_keep_transport_grid = st->choice_or("grid", t.static_keep_transport_grid ? "transport" : "lighting",
                                                     {"lighting", "transport"}) == "transport";
        t.static_monte_carlo = st->choice_or("solver", t.static_monte_carlo ? "monte_carlo" : "lattice",
                                             {"lattice", "monte_carlo"}) == "monte_carlo";
        t.static_toward_camera =
            st->choice_or("directions", t.static_toward_camera ? "camera" : "baked", {"baked", "camera"}) == "camera";
        if (t.static_toward_camera && !t.static_monte_carlo)
            st->fail("directions",
                     "\"camera\" needs \"solver\": \"monte_carlo\" (the lattice solves fixed directions)");
        // Whole paths through a thick cloud scatter hundreds of times: ~13 us of a core each on
        // the default storm (its moon and sky, 3 x 4M paths, in 78 s on 2 cores), so 2^26 bound
        // a light to about 7 minutes there.
        t.static_paths =
            std::uint64_t(st->integer_or("paths", std::int64_t(t.static_paths), 1000, std::int64_t(1) << 26));
        // Bounded so a solve ends: 2^27 paths are ~2 min on one core of this machine.
        t.static_order2_paths = std::uint64_t(
            st->integer_or("order2_paths", std::int64_t(t.static_order2_paths), 1000, std::int64_t(1) << 27));
        t.static_sky_samples = int(st->integer_or("sky_samples", t.static_sky_samples, 1, 1024));
        // As order2_paths: 2^27 paths bound a solve to minutes.
        t.static_sky_paths =
            std::uint64_t(st->integer_or("sky_paths", std::int64_t(t.static_sky_paths), 0, std::int64_t(1) << 27));
        if (t.static_sky_paths > 0 && t.static_sky_paths < 1000)
            st->fail("sky_paths",
                     "must be 0 (the dome as directions) or at least 1000, got " + std::to_string(t.static_sky_paths));
        st->finish();
    }
    if (auto ss = o.optional_object("single_scattering")) {
        // transport::SingleScatteringOptions accepts [1e-9, 0.5].
        t.ss_tolerance = ss->number_or("tolerance", t.ss_tolerance, Range{1e-9, 0.5});
        ss->finish();
    }
    if (auto mc = o.optional_object("monte_carlo")) {
        t.mc_paths = std::uint64_t(mc->integer_or("paths", std::int64_t(t.mc_paths), 1000, std::int64_t(1) << 40));
        t.mc_seed = mc->seed_or("seed", t.mc_seed);
        t.mc_batches = int(mc->integer_or("batches", t.mc_batches, 2, 1024));
        mc->finish();
    }
    o.finish();
}

void parse_virtual_lights(JsonObject o, basis::VirtualLightParams& v, double& drop_below) {
    v.h_usr = o.number_or("h_usr", v.h_usr, Range{0.0, 1e6, true, false});
    // 1/m^2. Any epsilon >= 1/h_usr^2 already puts the layer after the first one on the
    // ground; the upper bound only rejects nonsense.
    v.epsilon = o.number_or("epsilon", v.epsilon, Range{0.0, 1e6});
    v.margin = o.number_or("margin", v.margin, Range{0.0, 1e6});
    v.ground_height = o.number_or("ground_height", v.ground_height, Range{-1e6, 1e6});
    v.density_threshold = o.number_or("density_threshold", v.density_threshold, Range{0.0, 1.0, false, true});
    // A light scatters at most its whole power (fraction <= albedo <= 1): 1 drops every light.
    drop_below = o.number_or("drop_below", drop_below, Range{0.0, 1.0, false, true});
    o.finish();
    validated_as_pointer(o.file(), [&] { basis::validate(v, "virtual_lights"); });
}

void parse_compression(JsonObject o, basis::CompressionParams& c, bool& separate_components) {
    const std::string mode =
        o.choice_or("threshold", std::string(basis::to_string(c.mode)), {"absolute", "relative_l2", "energy"});
    c.mode = mode == "absolute"      ? basis::ThresholdMode::Absolute
             : mode == "relative_l2" ? basis::ThresholdMode::RelativeL2
                                     : basis::ThresholdMode::Energy;
    if (c.mode == basis::ThresholdMode::Energy)
        c.xi =
            o.number_or("xi", c.xi, Range{0.0, 1.0, true, false});  // fraction of each basis' energy kept; 0 keeps none
    else if (o.has("xi"))
        // absolute: units of S; relative_l2: fraction of ||B||, and no |B| exceeds ||B||: 1 keeps none
        c.xi = o.number("xi",
                        c.mode == basis::ThresholdMode::RelativeL2 ? Range{0.0, 1.0, false, true} : Range{0.0, 1e30});
    else
        o.fail("xi", std::string("required with threshold \"") + mode + "\" (the default xi belongs to \"energy\")");
    const std::string prec =
        o.choice_or("precision", std::string(basis::to_string(c.precision)), {"float32", "float16"});
    c.precision = prec == "float32" ? basis::Precision::Float32 : basis::Precision::Float16;
    const std::string dec =
        o.choice_or("decomposition", std::string(basis::to_string(c.decomposition)), {"nonstandard", "standard"});
    c.decomposition = dec == "standard" ? basis::Decomposition::Standard : basis::Decomposition::NonStandard;
    c.entropy = o.choice_or("entropy", std::string(basis::to_string(c.entropy)), {"deflate", "none"}) == "none"
                    ? basis::Entropy::None
                    : basis::Entropy::Deflate;
    separate_components = o.choice_or("components", separate_components ? "separate" : "combined",
                                      {"separate", "combined"}) == "separate";
    o.finish();
    validated_as_pointer(o.file(), [&] { basis::validate(c, "compression"); });
}

// "colour": linear RGB, each channel in [0, 1000], scaled to luminance 1 (the magnitude is
// the light's irradiance or radiance); absent: `fallback`.
glm::dvec3 colour_or(JsonObject& o, std::string_view key, glm::dvec3 fallback) {
    if (!o.has(key)) return o.vec3_or(key, fallback, Range{0.0, 1e3});
    const glm::dvec3 c = o.vec3(key, Range{0.0, 1e3});
    const double y = luminance(c);
    if (!(y > 1e-9)) o.fail(key, "must have a positive luminance (0.2126 r + 0.7152 g + 0.0722 b > 0)");
    return c / y;
}

// The largest sun irradiance (W/m^2) or point intensity (W/sr) a scene may declare: the
// renderer carries radiance in float32 (largest 3.4e38), and a sun's disc is ~2e5 times its
// irradiance in its bluest channel (1/0.0722 over the disc's 6.8e-5 sr), which leaves 1e3 of
// headroom for the march's sums at 1e30. (The sun is 1361 W/m^2.)
constexpr double kMaxLight = 1e30;

void parse_sun(JsonObject& l, Scene& s) {
    if (s.sun) l.fail("type", "a scene has at most one sun (a moon is a dim sun)");
    Sun sun;
    const bool has_dir = l.has("direction"), has_el = l.has("elevation"), has_az = l.has("azimuth");
    if (has_dir == (has_el || has_az))
        l.fail("direction", "give either \"direction\" [x, y, z] or \"elevation\" and \"azimuth\" (degrees)");
    if (has_dir) {
        const glm::dvec3 d = l.vec3("direction", Range{-1e6, 1e6});
        if (glm::length(d) < 1e-9) l.fail("direction", "must be a non-zero vector");
        sun.direction = glm::normalize(d);
        // The propagation direction: a sun above the horizon sends its light downward, as
        // "elevation" in (0, 90] requires.
        if (!(sun.direction.z < 0.0))
            l.fail("direction",
                   "points along or above the horizon (z >= 0); it is the direction the light travels, "
                   "so a sun above the horizon has z < 0 (below it, the cloud is lit by the sky only)");
    } else {
        if (!has_el) l.fail("elevation", "required with \"azimuth\": degrees above the horizon in (0, 90]");
        if (!has_az) l.fail("azimuth", "required with \"elevation\": degrees from +x toward +y in [-360, 360]");
        // A sun at or below the horizon lights the cloud only through the sky: not a light here.
        const double el = l.number("elevation", Range{0.0, 90.0, true, false});
        const double az = l.number("azimuth", Range{-360.0, 360.0});
        sun.direction = sun_direction(el, az);
    }
    sun.irradiance = l.number_or("irradiance", sun.irradiance, Range{0.0, kMaxLight, true});
    sun.colour = colour_or(l, "colour", sun.colour);
    sun.name = l.string_or("name", "");
    s.sun = sun;
}

void parse_lights(JsonObject& root, Scene& s) {
    for (JsonObject& l : root.objects("lights")) {
        const std::string type = l.choice_or("type", "", {"point", "sun"});
        if (type.empty()) l.fail("type", "required: \"point\" or \"sun\"");
        if (type == "point") {
            transport::PointSource p;
            p.position = l.vec3("position", Range{-1e7, 1e7});
            p.intensity = l.number_or("intensity", p.intensity, Range{0.0, kMaxLight});
            s.point_lights.push_back(p);
        } else {
            parse_sun(l, s);
        }
        l.finish();
    }
}

// "sky": {"radiance": r, "colour": c} (uniform) or {"zenith": {...}, "horizon": {...}}.
void parse_sky(JsonObject o, Scene& s) {
    SkyDome sky;
    // Radiance in W m^-2 sr^-1: up to 1e6 (a clear day sky is ~10^2 in these units).
    const Range radiance{0.0, 1e6};
    const bool uniform = o.has("radiance") || o.has("colour"), gradient = o.has("zenith") || o.has("horizon");
    if (uniform == gradient)
        o.fail("radiance",
               "give either \"radiance\" and \"colour\" (a uniform sky) or \"zenith\" and "
               "\"horizon\" (a gradient), each {\"radiance\": r, \"colour\": [r, g, b]}");
    if (uniform) {
        sky.zenith_radiance = sky.horizon_radiance = o.number("radiance", radiance);
        sky.zenith_colour = sky.horizon_colour = colour_or(o, "colour", sky.zenith_colour);
    } else {
        JsonObject z = o.object("zenith"), h = o.object("horizon");
        sky.zenith_radiance = z.number("radiance", radiance);
        sky.zenith_colour = colour_or(z, "colour", sky.zenith_colour);
        z.finish();
        sky.horizon_radiance = h.number("radiance", radiance);
        sky.horizon_colour = colour_or(h, "colour", sky.horizon_colour);
        h.finish();
    }
    sky.star_radiance = o.number_or("stars", sky.star_radiance, Range{0.0, 1e6});
    o.finish();
    s.sky = sky;
}

void parse_effects(JsonObject o, Effects& e) {
    e.lightning = o.boolean_or("lightning", e.lightning);
    e.single_scattering = o.boolean_or("single_scattering", e.single_scattering);
    e.multiple_scattering = o.boolean_or("multiple_scattering", e.multiple_scattering);
    e.sun = o.boolean_or("sun", e.sun);
    e.sky = o.boolean_or("sky", e.sky);
    e.glow = o.boolean_or("glow", e.glow);
    e.glare = o.boolean_or("glare", e.glare);
    e.ground = o.boolean_or("ground", e.ground);
    o.finish();
}

void parse_lightning(JsonObject o, Scene& s) {
    lightning::LightningParams& l = s.lightning;
    s.lightning_colour = colour_or(o, "colour", s.lightning_colour);
    // Ranges: the same as lightning::validate (engine/lightning/params.cpp).
    lightning::BoltParams& b = l.bolt;
    const std::string kind = o.choice_or("kind", std::string(lightning::kind_name(b.kind)),
                                         {"cloud_to_ground", "intra_cloud", "cloud_to_cloud"});
    b.kind = kind == "intra_cloud"      ? lightning::Kind::IntraCloud
             : kind == "cloud_to_cloud" ? lightning::Kind::CloudToCloud
                                        : lightning::Kind::CloudToGround;
    l.seed = o.seed_or("seed", l.seed);
    b.intensity = o.number_or("intensity", b.intensity, Range{0.0, 1e12});
    b.start_density_threshold =
        o.number_or("start_density_threshold", b.start_density_threshold, Range{0.0, 1.0, false, true});
    b.ground_height = o.number_or("ground_height", b.ground_height, Range{-1e4, 5e4});
    b.angle_mean_deg = o.number_or("angle_mean", b.angle_mean_deg, Range{0.0, 90.0});
    b.angle_spread_deg = o.number_or("angle_spread", b.angle_spread_deg, Range{0.0, 60.0});
    b.segment_length_mean = o.number_or("segment_length_mean", b.segment_length_mean, Range{1.0, 5000.0});
    b.segment_length_spread = o.number_or("segment_length_spread", b.segment_length_spread, Range{0.0, 5000.0});
    b.target_bias = o.number_or("target_bias", b.target_bias, Range{0.0, 1.0});
    b.wander = o.number_or("wander", b.wander, Range{0.0, 2.0});
    b.zigzag = o.number_or("zigzag", b.zigzag, Range{0.0, 4.0});
    b.max_segments = int(o.integer_or("max_segments", b.max_segments, 1, 1'000'000));
    if (auto br = o.optional_object("branches")) {
        b.branch_probability = br->number_or("probability", b.branch_probability, Range{0.0, 1.0});
        b.branch_angle_mean_deg = br->number_or("angle_mean", b.branch_angle_mean_deg, Range{0.0, 90.0});
        b.branch_length_fraction =
            br->number_or("length_fraction", b.branch_length_fraction, Range{0.0, 1.0, true, false});
        b.branch_intensity_decay = br->number_or("intensity_decay", b.branch_intensity_decay, Range{0.0, 1.0});
        b.max_depth = int(br->integer_or("max_depth", b.max_depth, 0, 8));
        br->finish();
    }
    if (auto t = o.optional_object("timing")) {
        lightning::TimingParams& p = l.timing;
        p.leader_speed = t->number_or("leader_speed", p.leader_speed, Range{1e3, 1e8});
        p.leader_brightness = t->number_or("leader_brightness", p.leader_brightness, Range{0.0, 1.0});
        p.rise_time = t->number_or("rise_time", p.rise_time, Range{0.0, 0.01});
        p.decay_time = t->number_or("decay_time", p.decay_time, Range{0.0, 1.0, true, false});
        p.restrikes = t->number_or("restrikes", p.restrikes, Range{0.0, 20.0});
        p.restrikes_max = int(t->integer_or("restrikes_max", p.restrikes_max, 0, 32));
        p.restrike_interval = t->number_or("restrike_interval", p.restrike_interval, Range{0.001, 1.0});
        p.restrike_brightness = t->number_or("restrike_brightness", p.restrike_brightness, Range{0.0, 10.0});
        p.dart_leader_speed = t->number_or("dart_leader_speed", p.dart_leader_speed, Range{1e5, 1e9});
        p.dark_threshold = t->number_or("dark_threshold", p.dark_threshold, Range{0.0, 0.5, true, false});
        t->finish();
    }
    l.schedule.strike_rate = o.number_or("strike_rate", l.schedule.strike_rate, Range{0.0, 100.0});
    l.schedule.first_strike = o.number_or("first_strike", l.schedule.first_strike, Range{0.0, 1e6});
    o.finish();
    // The same ranges, kept in one place for code users; their dotted field as a JSON pointer.
    validated_as_pointer(o.file(), [&] { lightning::validate(l, "lightning"); });
}

// "camera": {"position", "target", "up"?, "vertical_fov"?} or {"orbit": {"azimuth",
// "elevation", "distance"?, "target"?}, "vertical_fov"?}.
CameraSpec parse_camera_object(JsonObject o) {
    CameraSpec c;
    const Range coordinate{-1e7, 1e7};
    c.vertical_fov_deg = o.number_or("vertical_fov", c.vertical_fov_deg, Range{1.0, 170.0});
    if (auto orbit = o.optional_object("orbit")) {
        for (const char* k : {"position", "target", "up"})
            if (o.has(k))
                o.fail(k,
                       "does not go with \"orbit\" (an orbit's target is orbit.target; its position follows "
                       "from azimuth, elevation and distance)");
        c.kind = CameraSpec::Kind::Orbit;
        c.azimuth_deg = orbit->number("azimuth", Range{-360.0, 360.0});
        c.elevation_deg = orbit->number("elevation", Range{-89.0, 89.0});
        if (orbit->has("distance")) c.distance = orbit->number("distance", Range{1.0, 1e7});
        if (orbit->has("target")) c.orbit_target = orbit->vec3("target", coordinate);
        orbit->finish();
    } else {
        c.kind = CameraSpec::Kind::LookAt;
        c.position = o.vec3("position", coordinate);
        c.target = o.vec3("target", coordinate);
        c.up = o.vec3_or("up", c.up, coordinate);
        const glm::dvec3 view = c.target - c.position;
        if (glm::length(view) < 1e-3) o.fail("target", "is the camera's position: the camera looks nowhere");
        if (glm::length(c.up) == 0.0) o.fail("up", "is the zero vector");
        if (glm::length(glm::cross(glm::normalize(view), glm::normalize(c.up))) < 1e-3)
            o.fail("up", "is parallel to the view direction (target - position): the image has no up");
    }
    o.finish();
    return c;
}

}  // namespace

Scene parse_scene(std::string_view json_text, std::string_view file_name, const std::filesystem::path& base_dir) {
    const std::string file(file_name);
    const nlohmann::json j = detail::parse_json(json_text, file);
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
    if (auto v = root.optional_object("virtual_lights")) parse_virtual_lights(*v, s.virtual_lights, s.drop_below);
    if (auto c = root.optional_object("compression")) parse_compression(*c, s.compression, s.separate_components);
    parse_lights(root, s);
    if (auto sky = root.optional_object("sky")) parse_sky(*sky, s);
    if (auto rain = root.optional_object("rain")) s.rain = parse_rain(*rain);
    // What the scene declares is what it calls for, unless "effects" says otherwise.
    s.effects.sun = s.sun.has_value();
    s.effects.sky = s.sky.has_value();
    if (auto e = root.optional_object("effects")) parse_effects(*e, s.effects);
    if (auto l = root.optional_object("lightning")) parse_lightning(*l, s);
    if (root.is_string("quality")) {
        const std::string name = root.choice_or("quality", "paper", kQualityPresets);
        s.quality = quality_preset(name);
    } else if (auto q = root.optional_object("quality")) {
        s.quality = quality_preset(q->choice_or("preset", "paper", kQualityPresets));
        Quality& k = s.quality;
        constexpr std::int64_t kMaxPaths = std::int64_t(1) << 32;
        k.single_paths = std::uint64_t(q->integer_or("single_paths", std::int64_t(k.single_paths), 1000, kMaxPaths));
        k.multiple = q->choice_or("multiple", k.multiple, {"none", "lattice", "monte_carlo"});
        k.multiple_paths = std::uint64_t(q->integer_or("multiple_paths", std::int64_t(k.multiple_paths), 0, kMaxPaths));
        if (k.multiple == "monte_carlo" && k.multiple_paths < 1000)
            q->fail("multiple_paths", "must be >= 1000 with \"multiple\": \"monte_carlo\"");
        k.lookahead = q->number_or("lookahead", k.lookahead, Range{0.0, 60.0});
        k.refine = int(q->integer_or("refine", k.refine, 0, 64));
        k.exact_orders = int(q->integer_or("exact_orders", k.exact_orders, 0, 2));
        k.keep_transport_grid = q->choice_or("grid", "lighting", {"lighting", "transport"}) == "transport";
        if (k.keep_transport_grid && (k.preset == Quality::Preset::Paper || k.preset == Quality::Preset::Instant))
            q->fail("grid", std::string("the ") + std::string(to_string(k.preset)) +
                                " preset keeps no solved strike's light: must be \"lighting\"");
        k.toward_camera = q->choice_or("directions", "baked", {"baked", "camera"}) == "camera";
        k.target_noise = q->number_or("target_noise", k.target_noise, Range{1e-4, 1.0});
        k.max_change_per_frame = q->number_or("max_change_per_frame", k.max_change_per_frame, Range{1e-3, 1e3});
        k.near_field_rays = int(q->integer_or("near_field_rays", k.near_field_rays, 0, 4096));
        k.near_field_multiple = q->choice_or("near_field_multiple", k.near_field_multiple, {"kernel", "diffusion"});
        k.near_field_fine_rays = int(q->integer_or("near_field_fine_rays", k.near_field_fine_rays, 0, 4096));
        if (k.preset == Quality::Preset::Instant && k.multiple != "monte_carlo")
            q->fail("multiple",
                    "the instant preset traces multiple scattering by Monte Carlo: must be \"monte_carlo\"");
        if (k.preset == Quality::Preset::Paper && k.multiple != "none")
            q->fail("multiple", "the paper preset solves nothing per strike: must be \"none\"");
        if (k.toward_camera)
            if (const std::string why = toward_camera_problem(k); !why.empty()) q->fail("directions", why);
        q->finish();
    }
    if (auto c = root.optional_object("camera")) s.camera = parse_camera_object(*c);
    if (auto l = root.optional_object("limits")) {
        s.limits.memory_bytes = l->number_or("memory_gib", 0.0, Range{0.0, 1e6}) * double(1ull << 30);
        s.limits.bake_seconds =
            l->number_or("bake_hours", s.limits.bake_seconds / 3600.0, Range{0.0, 1e6, true}) * 3600.0;
        s.limits.strike_seconds =
            l->number_or("strike_minutes", s.limits.strike_seconds / 60.0, Range{0.0, 1e6, true}) * 60.0;
        l->finish();
    }
    root.finish();
    if (s.effects.sun && !s.sun)
        throw core::Error(file + ": /effects/sun", "true needs a light of type \"sun\" in \"lights\"");
    if (s.effects.sky && !s.sky) throw core::Error(file + ": /effects/sky", "true needs a \"sky\" section");
    if (s.quality.refine > 0 && s.lighting_downsample % s.quality.refine != 0)
        throw core::Error(file + ": /quality/refine", "must divide /lighting/downsample (" +
                                                          std::to_string(s.lighting_downsample) + "), got " +
                                                          std::to_string(s.quality.refine));
    if (s.quality.keep_transport_grid && std::max(s.quality.refine, s.transport.refine) <= 1)
        throw core::Error(file + ": /quality/grid",
                          "\"transport\" keeps the strikes on the per-strike transport grid, which here is the "
                          "lighting grid (quality.refine and transport.refine are 1): set quality.refine to a "
                          "divisor of /lighting/downsample (" +
                              std::to_string(s.lighting_downsample) + ") above 1, or use \"lighting\"");
    // The lattice carries S on its own directions: 6 output directions are not a lattice set.
    if (s.effects.multiple_scattering && s.transport.solver == TransportSettings::Solver::LatticeBoltzmann &&
        s.effective_directions() == 6)
        throw core::Error(file + ": /lighting/directions",
                          "6 output directions do not go with the lattice-Boltzmann solver, which needs 1, 18 or 26 "
                          "(its own directions); choose 18 or 26, or transport.solver \"monte_carlo\"");
    // A light scatters at most the albedo's fraction of its power into the cloud.
    if (s.drop_below > 0.0 && s.drop_below >= s.medium.albedo)
        throw core::Error(file + ": /virtual_lights/drop_below",
                          core::format_number(s.drop_below) +
                              " drops every light: no light scatters more than medium.albedo (" +
                              core::format_number(s.medium.albedo) + ") of its power; the bake would light nothing");
    if (s.transport.static_refine > 0 && s.lighting_downsample % s.transport.static_refine != 0)
        throw core::Error(file + ": /transport/static_light/refine",
                          "must divide /lighting/downsample (" + std::to_string(s.lighting_downsample) + "), got " +
                              std::to_string(s.transport.static_refine));
    if (s.lighting_downsample % s.transport.refine != 0)
        throw core::Error(file + ": /transport/refine", "must divide /lighting/downsample (" +
                                                            std::to_string(s.lighting_downsample) + "), got " +
                                                            std::to_string(s.transport.refine));
    return s;
}

glm::dvec3 sun_direction(double elevation_deg, double azimuth_deg) noexcept {
    const double el = elevation_deg * std::numbers::pi / 180.0, az = azimuth_deg * std::numbers::pi / 180.0;
    return -glm::dvec3(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
}

void sun_angles(const glm::dvec3& direction, double& elevation_deg, double& azimuth_deg) noexcept {
    const glm::dvec3 to_sun = -direction;
    elevation_deg = std::asin(std::clamp(to_sun.z, -1.0, 1.0)) * 180.0 / std::numbers::pi;
    azimuth_deg = std::atan2(to_sun.y, to_sun.x) * 180.0 / std::numbers::pi;
}

Scene load_scene(const std::filesystem::path& path) {
    const std::string text = core::read_file(path, kMaxSceneBytes, "scene");
    Scene s = parse_scene(text, path.string(), path.parent_path());
    s.path = path;
    return s;
}

std::string_view to_string(Quality::Preset p) noexcept {
    const auto i = std::size_t(p);
    return i < kQualityPresets.size() ? kQualityPresets[i] : "?";
}

int strike_refine(const Scene& s, const Quality& q) noexcept {
    return q.refine > s.transport.refine && s.lighting_downsample % q.refine == 0 ? q.refine : s.transport.refine;
}

namespace {
std::optional<glm::dvec3> camera_if(bool toward, const Scene& s, const core::GridGeometry& density) {
    if (!toward || s.medium.g == 0.0) return std::nullopt;
    return camera_position(s.camera, density);
}
}  // namespace

std::optional<glm::dvec3> strike_toward(const Scene& s, const Quality& q, const core::GridGeometry& density) {
    return camera_if(q.toward_camera, s, density);
}

std::optional<glm::dvec3> static_toward(const Scene& s, const core::GridGeometry& density) {
    return camera_if(s.transport.static_monte_carlo && s.transport.static_toward_camera, s, density);
}

std::string toward_camera_problem(const Quality& q) {
    if (q.preset == Quality::Preset::Paper || q.preset == Quality::Preset::Instant)
        return "\"camera\": the " + std::string(to_string(q.preset)) +
               " preset solves no strike ahead; use hybrid, per_strike_mc or reference";
    if (q.multiple == "lattice")
        return "\"camera\" needs the strike's solve by Monte Carlo alone (\"multiple\": \"monte_carlo\" or "
               "\"none\"): the lattice solves fixed directions";
    return {};
}

Quality quality_preset(std::string_view name, std::string_view where) {
    Quality q;
    if (name == "paper") {
        q.preset = Quality::Preset::Paper;
    } else if (name == "hybrid") {
        q.preset = Quality::Preset::Hybrid;
    } else if (name == "per_strike") {
        q.preset = Quality::Preset::PerStrike;
        q.multiple = "lattice";
        // The lattice on 2x finer voxels with order 2 exact (where 2 divides the lighting
        // grid's downsample): the per-strike lattice docs/presets.md measures at 12% from the
        // truth, against 47% on the lighting grid.
        q.refine = 2;
        q.exact_orders = 2;
    } else if (name == "per_strike_mc") {
        // Monte Carlo for both parts, 50k paths each: docs/presets.md measures it at 7.0% of the
        // truth on the default storm's worst strike (about 3% on the others) at under a second
        // per strike, ahead of every lattice configuration.
        q.preset = Quality::Preset::PerStrikeMc;
        q.single_paths = 50'000;
        q.multiple = "monte_carlo";
        q.multiple_paths = 50'000;
    } else if (name == "instant") {
        // Monte Carlo of both parts traced progressively from the moment a strike is known, on
        // every core the frame leaves free, and shown blended with the bases by its own noise
        // estimate: no lookahead needed (docs/presets.md measures the error against wall time).
        // The path counts are caps; target_noise usually stops the solve first.
        q.preset = Quality::Preset::Instant;
        q.single_paths = 1'000'000;
        q.multiple = "monte_carlo";
        q.multiple_paths = 1'000'000;
        // Until a strike's first estimate, the bases' frame with the near-field correction:
        // 32 rays per point halve the first frame's error on the default storm (75.7% ->
        // 35.7%) for a few milliseconds once per strike (docs/presets.md).
        q.near_field_rays = 32;
        // Instead of the kernel, the strike's own light: its rays' single scattering and a
        // flux-limited diffusion solve, 35.5% -> 23.2% worst on the default storm for 4.4 ms once
        // per strike (docs/presets.md).
        q.near_field_multiple = "diffusion";
        // Its single scattering through the full-resolution density, 128 rays per point: 23.2% ->
        // 18.6% worst on the default storm for 6-7 ms more once per strike (docs/presets.md).
        q.near_field_fine_rays = 128;
    } else if (name == "reference") {
        q.preset = Quality::Preset::Reference;
        q.single_paths = 4'000'000;
        q.multiple = "monte_carlo";
        q.multiple_paths = 4'000'000;
    } else {
        std::string list;
        for (std::string_view n : kQualityPresets) list += (list.empty() ? "" : ", ") + std::string(n);
        throw core::Error(std::string(where), "must be one of " + list + "; got \"" + std::string(name) + "\"");
    }
    return q;
}

namespace {

// Runs a VDB read, naming the scene file and the cloud's field in its errors.
template <class F>
auto vdb_cloud_errors(const Scene& s, F&& f) {
    try {
        return f();
    } catch (const core::Error& e) {
        const std::string scene_file = s.file_name();
        // Errors about the grid the scene names (missing, not float, empty, its transform or
        // values) are the "grid" field's; the others (file missing or not a VDB) the "vdb" field's.
        const std::string named = s.cloud.file.string() + ": grid \"" + s.cloud.vdb.grid + "\"";
        const bool grid = !s.cloud.vdb.grid.empty() && e.where().starts_with(named);
        throw core::Error(scene_file + (grid ? ": /cloud/grid" : ": /cloud/vdb"), e.what());
    }
}

}  // namespace

cloud::VdbInfo inspect_vdb_cloud(const Scene& s) {
    FULGUR_ASSERT(s.cloud.kind == CloudSource::Kind::Vdb, "inspect_vdb_cloud needs a VDB cloud");
    return vdb_cloud_errors(s, [&] { return cloud::inspect_vdb(s.cloud.file, s.cloud.vdb); });
}

namespace {

// The bolts run between the ground and the top of the density grid (lightning::BoltGenerator):
// a ground the scene puts at or above that top is named here, with the file, rather than when
// the first bolt is made.
void check_ground_fits(const Scene& s, const core::GridGeometry& density) {
    if (!s.effects.lightning) return;
    const lightning::BoltParams& b = s.lightning.bolt;
    const double top = density.upper().z;
    if (!(b.ground_height + b.segment_length_mean < top))
        throw core::Error(s.file_name() + ": /lightning/ground_height",
                          core::format_number(b.ground_height, 8) + " m: the ground must lie more than a segment (" +
                              core::format_number(b.segment_length_mean, 8) +
                              " m) below the top of the cloud's grid (z = " + core::format_number(top, 8) + " m)");
}

core::Grid3<float> load_or_generate(const Scene& s) {
    if (s.cloud.kind == CloudSource::Kind::File) return cloud::load_density(s.cloud.file);
    if (s.cloud.kind == CloudSource::Kind::Vdb) {
        cloud::VdbImport v = s.cloud.vdb;
        v.max_bytes = std::uint64_t(memory_limit(s));
        return vdb_cloud_errors(s, [&] { return cloud::load_vdb(s.cloud.file, v); });
    }
    return cloud::generate_cumulonimbus(s.cloud.generator);
}

}  // namespace

core::Grid3<float> make_undetailed_density(const Scene& s) {
    check_cost(s, estimate_cost(s));
    core::Grid3<float> d = load_or_generate(s);
    check_ground_fits(s, d.geom);
    return d;
}

core::Grid3<float> add_detail(const Scene& s, const core::Grid3<float>& undetailed) {
    if (!s.cloud.detail) return undetailed;
    return cloud::detailed_density(undetailed, cloud::DetailNoise(*s.cloud.detail));
}

core::Grid3<float> make_density(const Scene& s) {
    core::Grid3<float> d = make_undetailed_density(s);
    return s.cloud.detail ? add_detail(s, d) : d;
}

transport::LightingMedium make_lighting_medium(const Scene& s, const core::Grid3<float>& density) {
    transport::LightingMedium m;
    m.density = core::downsample(density, s.lighting_downsample);
    m.optics = s.medium;
    return m;
}

transport::LightingMedium make_transport_medium(const Scene& s, const core::Grid3<float>& density) {
    transport::LightingMedium m;
    m.density = core::downsample(density, s.lighting_downsample / s.transport.refine);
    m.optics = s.medium;
    return m;
}

void default_orbit(const core::GridGeometry& g, double distance_factor, glm::dvec3& target, double& distance) {
    const glm::dvec3 ext = g.extent();
    target = g.origin + 0.5 * ext;
    target.z = g.origin.z + 0.33 * ext.z;
    distance = distance_factor * std::max({ext.x, ext.y, ext.z});
}

glm::dvec3 camera_position(const std::optional<CameraSpec>& spec, const core::GridGeometry& density) {
    const CameraSpec c = spec.value_or(CameraSpec{});
    if (c.kind == CameraSpec::Kind::LookAt) return c.position;
    glm::dvec3 target;
    double distance = 0.0;
    default_orbit(density, 1.1, target, distance);
    if (c.orbit_target) target = *c.orbit_target;
    if (c.distance) distance = *c.distance;
    // As render::Camera::orbit places it (test_view pins the two together).
    const double az = glm::radians(c.azimuth_deg), el = glm::radians(c.elevation_deg);
    return target + distance * glm::dvec3(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
}

CameraSpec parse_camera(std::string_view json_text, std::string_view source) {
    const std::string file(source);
    const nlohmann::json j = detail::parse_json(json_text, file);
    if (!j.is_object()) throw core::Error(file, "expected a JSON object (a scene's \"camera\")");
    return parse_camera_object(JsonObject(j, file, ""));
}

CameraSpec camera_argument(std::string_view value, std::string_view option) {
    const std::size_t first = value.find_first_not_of(" \t\r\n");
    if (first != std::string_view::npos && value[first] == '{') return parse_camera(value, option);
    if (value.empty()) throw core::Error(std::string(option), "needs a camera: JSON text or a file holding it");
    const std::filesystem::path file(value);
    const std::string named = std::string(option) + " " + file.string();
    try {
        return parse_camera(core::read_file(file, kMaxSceneBytes, "camera"), named);
    } catch (const core::Error& e) {
        if (std::string_view(e.what()).starts_with(named)) throw;
        throw core::Error(std::string(option), e.what());  // the file could not be read
    }
}

std::string camera_json(const CameraSpec& c, int digits) {
    auto num = [digits](double v) {
        if (digits > 0) return core::format_number(v, digits);
        char buf[32];
        const auto r = std::to_chars(buf, buf + sizeof buf, v);  // shortest text that reads back exactly
        return std::string(buf, r.ptr);
    };
    auto vec = [&](const glm::dvec3& v) { return "[" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + "]"; };
    std::string out = "{";
    if (c.kind == CameraSpec::Kind::Orbit) {
        out += "\"orbit\": {";
        if (c.orbit_target) out += "\"target\": " + vec(*c.orbit_target) + ", ";
        if (c.distance) out += "\"distance\": " + num(*c.distance) + ", ";
        out += "\"azimuth\": " + num(c.azimuth_deg) + ", \"elevation\": " + num(c.elevation_deg) + "}";
    } else {
        out += "\"position\": " + vec(c.position) + ", \"target\": " + vec(c.target) + ", \"up\": " + vec(c.up);
    }
    return out + ", \"vertical_fov\": " + num(c.vertical_fov_deg) + "}";
}

}  // namespace fulgur::scene
