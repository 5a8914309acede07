// Solving once: the keys of the sun's and the sky's solves, the light file, and
// load_or_solve (sky.h, docs/sky.md "The cache").
#include "sky/sky.h"

#include <zlib.h>
#include <glm/geometric.hpp>

#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace fulgur::sky {

namespace {

// Bump when a solve's algorithm changes what it writes for the same key (forces a new solve).
constexpr int kSkyAlgorithm = 2;
constexpr char kMagic[8] = {'F', 'G', 'L', 'I', 'G', 'H', 'T', '1'};
constexpr std::uint32_t kVersion = 1;
constexpr std::uint32_t kMaxDirections = 64, kMaxFields = 16, kMaxName = 64;
constexpr std::uint32_t kMaxDescription = 1u << 20;
/// Bytes of everything but the fields: magic, version, key, description, grid, directions,
/// counts, checksum.
constexpr std::uint64_t kMaxHeaderBytes = 64 + kMaxDescription + 24 * kMaxDirections;
/// A file read without a shape to check it against (a tool inspecting one): 4 GiB, as NRRD.
constexpr std::uint64_t kMaxUncheckedBytes = std::uint64_t(1) << 32;
/// The largest |S| a light file may hold, per unit light (1/sr). S is at most the albedo times
/// the Henyey-Greenstein peak, (1 + g) / (4 pi (1 - g)^2) (1.6e3 at g = 0.99), times the
/// fluence per unit light, which in a cloud is of order one (a few under a bright top); 1e6
/// leaves three decades above that and still refuses values no solve writes (3e38, 1e30).
constexpr double kMaxUnitS = 1e6;

// The rain the static media hold (static_media): it is made from the density, which the key
// has, and these parameters. No line without rain, so a dry scene keeps its key.
std::string rain_lines(const scene::Scene& s) {
    if (!s.rain) return {};
    const cloud::RainParams& r = *s.rain;
    std::ostringstream d;
    const auto num = [](double v) { return core::format_number(v, 17); };
    d << "sky.rain=" << num(r.rate) << "," << num(r.threshold) << "," << num(r.shear.x) << "," << num(r.shear.y) << ","
      << num(r.streak_scale) << "," << num(r.streak_strength) << "," << r.seed << "," << num(r.g) << ","
      << num(r.albedo) << "\n";
    // S read out with the drops' own phase function in the rain's cells (transport::PhaseMix).
    d << "sky.rain_phase=drops\n";
    return d.str();
}

std::string settings_lines(const SolveSettings& st) {
    std::ostringstream d;
    d << "sky.algorithm=" << kSkyAlgorithm << "\n";
    d << "sky.method=" << to_string(st.method) << "\n";
    d << "sky.single=" << st.single << "\n";
    d << "sky.multiple=" << st.multiple << "\n";
    d << "sky.refine=" << st.refine << "\n";
    // Only when set, so the keys (and cache files) of S on the lighting grid stay as they were.
    if (st.keep_transport_grid) d << "sky.grid=transport\n";
    if (st.method == Method::MonteCarlo) d << "sky.truth_paths=" << st.truth_paths << "\n";
    if (st.toward) {  // exact digits: a camera moved by a millimetre is another solve
        d << std::setprecision(17) << "sky.toward=" << st.toward->x << "," << st.toward->y << "," << st.toward->z
          << "\n";
        d << std::setprecision(6);
    }
    d << "sky.exact_orders=" << st.exact_orders << "\n";
    if (st.multiple && st.exact_orders == 2)
        d << "sky.order2_paths=" << st.order2_paths << "\nsky.order2_seed=" << st.seed << "\n";
    return d.str();
}

std::uint32_t crc_of(const std::string& bytes, std::size_t n) {
    uLong crc = ::crc32(0L, Z_NULL, 0);
    std::size_t done = 0;
    while (done < n) {
        const uInt chunk = uInt(std::min<std::size_t>(n - done, 1u << 30));
        crc = ::crc32(crc, reinterpret_cast<const Bytef*>(bytes.data() + done), chunk);
        done += chunk;
    }
    return std::uint32_t(crc);
}

template <class T>
void put(std::string& out, T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    out.append(b, sizeof(T));
}

/// Bounded little-endian reads; every error names the file and the byte offset.
struct Reader {
    const std::string& bytes;
    std::size_t end;  // the checksum's offset
    std::string name;
    std::size_t at = 0;
    [[noreturn]] void fail(const std::string& what) const {
        throw core::Error(name + " (byte " + std::to_string(at) + ")", what);
    }
    template <class T>
    T get(const char* what) {
        if (end - at < sizeof(T)) fail(std::string("truncated: ") + what + " runs past the end of the data");
        T v;
        std::memcpy(&v, bytes.data() + at, sizeof(T));
        at += sizeof(T);
        return v;
    }
    std::string text(std::size_t n, const char* what) {
        if (end - at < n) fail(std::string("truncated: ") + what + " runs past the end of the data");
        std::string s = bytes.substr(at, n);
        at += n;
        return s;
    }
};

/// Refuses a light file solved on another grid or for other directions than the scene's plan
/// asks for (it would be composed with the other lights' fields cell by cell).
void check_shape(const std::string& name, const core::GridGeometry& g, const std::vector<glm::dvec3>& dirs,
                 const LightFileShape& shape) {
    const core::GridGeometry& want = shape.grid;
    if (!(g == want))
        throw core::Error(name, "solved on a " + std::to_string(g.dims.x) + " x " + std::to_string(g.dims.y) + " x " +
                                    std::to_string(g.dims.z) + " grid of " + core::format_number(g.voxel_size) +
                                    " m voxels, not this scene's lighting grid (" + std::to_string(want.dims.x) +
                                    " x " + std::to_string(want.dims.y) + " x " + std::to_string(want.dims.z) + " of " +
                                    core::format_number(want.voxel_size) + " m)");
    bool same = dirs.size() == shape.directions.size();
    for (std::size_t m = 0; same && m < dirs.size(); ++m)
        same = glm::length(dirs[m] - glm::normalize(shape.directions[m])) < 1e-9;
    if (!same)
        throw core::Error(name, "holds " + std::to_string(dirs.size()) + " output directions, not the scene's " +
                                    std::to_string(shape.directions.size()));
}

/// Every value finite and within what a solve writes: |S| <= kMaxUnitS, and no negative value
/// deeper than the field's largest positive one (the lattice's over-relaxed collision can
/// undershoot a little near a steep source; it never inverts a field).
void check_values(Reader& r, const NamedField& nf) {
    const std::vector<float>& v = nf.field.data;
    float lo = 0.0f, hi = 0.0f;
    std::size_t lo_at = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
        if (!std::isfinite(v[i]) || std::fabs(v[i]) > kMaxUnitS) {
            r.at += i * sizeof(float);
            r.fail("field \"" + nf.name + "\": value " + std::to_string(i) + " (" + core::format_number(v[i]) +
                   ") is not finite or beyond the " + core::format_number(kMaxUnitS) + " a solve can write");
        }
        if (v[i] < lo) lo = v[i], lo_at = i;
        hi = std::max(hi, v[i]);
    }
    if (-lo > hi) {
        r.at += lo_at * sizeof(float);
        r.fail("field \"" + nf.name + "\": value " + std::to_string(lo_at) + " (" + core::format_number(lo) +
               ") lies further below zero than the field's largest value (" + core::format_number(hi) +
               ") lies above it: not a solve's output");
    }
}

std::vector<NamedField> light_fields(const LightField& f, const std::string& prefix) {
    std::vector<NamedField> out;
    if (!f.single.data.empty()) out.push_back({prefix + "single", f.single});
    if (!f.multiple.data.empty()) out.push_back({prefix + "multiple", f.multiple});
    return out;
}

LightField field_of(std::vector<NamedField>& fields, const std::string& prefix) {
    LightField f;
    for (NamedField& n : fields) {
        if (n.name == prefix + "single") f.single = std::move(n.field);
        if (n.name == prefix + "multiple") f.multiple = std::move(n.field);
    }
    return f;
}

}  // namespace

basis::BakeKey sun_key(const scene::Scene& s, const core::Grid3<float>& density, const SolveSettings& settings,
                       const glm::dvec3& direction) {
    std::ostringstream d;
    d << bake::scene_key(s, density).description << settings_lines(settings) << rain_lines(s);
    d << "sky.light=sun\n";
    d << "sky.sun.direction=" << core::format_number(direction.x, 17) << "," << core::format_number(direction.y, 17)
      << "," << core::format_number(direction.z, 17) << "\n";
    return basis::BakeKey::from_description(d.str());
}

basis::BakeKey sky_key(const scene::Scene& s, const core::Grid3<float>& density, const SolveSettings& settings,
                       bool uniform) {
    std::ostringstream d;
    d << bake::scene_key(s, density).description << settings_lines(settings) << rain_lines(s);
    d << "sky.light=dome\n";
    d << "sky.dome.uniform=" << uniform << "\n";
    // The dome as directions keeps its key; by Monte Carlo its paths replace the samples.
    if (settings.sky_paths > 0)
        d << "sky.dome.paths=" << settings.sky_paths << "\n";
    else
        d << "sky.dome.samples=" << settings.sky_samples << "\n";
    return basis::BakeKey::from_description(d.str());
}

void write_light_file(const std::filesystem::path& path, const basis::BakeKey& key,
                      std::span<const NamedField> fields) {
    FULGUR_ASSERT(fields.size() <= kMaxFields, "write_light_file: too many fields");
    std::string out;
    out.append(kMagic, sizeof kMagic);
    put(out, kVersion);
    put(out, key.hash);
    put(out, std::uint32_t(key.description.size()));
    out += key.description;
    const core::GridGeometry g = fields.empty() ? core::GridGeometry{} : fields.front().field.geom;
    const std::vector<glm::dvec3> dirs = fields.empty() ? std::vector<glm::dvec3>{} : fields.front().field.directions;
    put(out, std::int32_t(g.dims.x));
    put(out, std::int32_t(g.dims.y));
    put(out, std::int32_t(g.dims.z));
    put(out, g.voxel_size);
    put(out, g.origin.x);
    put(out, g.origin.y);
    put(out, g.origin.z);
    put(out, std::uint32_t(dirs.size()));
    for (const glm::dvec3& v : dirs) {
        put(out, v.x);
        put(out, v.y);
        put(out, v.z);
    }
    put(out, std::uint32_t(fields.size()));
    for (const NamedField& f : fields) {
        bool same_dirs = f.field.directions.size() == dirs.size();
        for (std::size_t m = 0; same_dirs && m < dirs.size(); ++m)
            same_dirs = glm::length(f.field.directions[m] - dirs[m]) < 1e-9;  // normalized copies may round apart
        FULGUR_ASSERT(f.field.geom == g && same_dirs && f.field.data.size() == g.cell_count() * dirs.size(),
                      "write_light_file: fields must share one grid and direction set");
        FULGUR_ASSERT(!f.name.empty() && f.name.size() <= kMaxName, "write_light_file: field name length");
        put(out, std::uint32_t(f.name.size()));
        out += f.name;
        out.append(reinterpret_cast<const char*>(f.field.data.data()), f.field.data.size() * sizeof(float));
    }
    put(out, crc_of(out, out.size()));
    core::write_file(path, out);  // atomically, under the file's lock: a partial file never replaces a good one
}

std::vector<NamedField> read_light_file(const std::filesystem::path& path, const basis::BakeKey* expected,
                                        const LightFileShape* shape) {
    // Sized before it is read: a FIFO, a device or a file larger than the shape allows is
    // refused by the file check, never read into memory.
    std::uint64_t max_bytes = kMaxUncheckedBytes;
    if (shape) {
        const std::uint64_t floats = std::uint64_t(shape->grid.cell_count()) * shape->directions.size();
        max_bytes = kMaxHeaderBytes + shape->names.size() * (4 + kMaxName + 4 * floats);
    }
    const std::string bytes = core::read_file(path, max_bytes, "light");
    const std::string name = path.string();
    if (bytes.size() < sizeof kMagic + 4 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
        throw core::Error(name + " (byte 0)", "not a Fulgur light file (expected the magic \"FGLIGHT1\")");
    Reader r{bytes, bytes.size() - 4, name};
    r.at = sizeof kMagic;
    const auto version = r.get<std::uint32_t>("the version");
    if (version != kVersion)
        r.fail("format version " + std::to_string(version) + " is not supported (this build reads " +
               std::to_string(kVersion) + ")");
    std::uint32_t crc_stored;
    std::memcpy(&crc_stored, bytes.data() + r.end, 4);
    if (crc_of(bytes, r.end) != crc_stored)
        throw core::Error(name + " (byte " + std::to_string(r.end) + ")",
                          "checksum mismatch: the file is corrupt or truncated");
    basis::BakeKey key;
    key.hash = r.get<std::uint64_t>("the key hash");
    const auto desc_len = r.get<std::uint32_t>("the key description's length");
    if (desc_len > kMaxDescription) r.fail("key description of " + std::to_string(desc_len) + " bytes is too long");
    key.description = r.text(desc_len, "the key description");
    if (basis::hash_description(key.description) != key.hash) r.fail("the key's hash does not match its description");
    if (expected && !(key == *expected))
        throw core::Error(name, "stale light file: solved for other parameters; " +
                                    basis::key_difference(key, *expected) + "; it is solved again");
    core::GridGeometry g;
    g.dims.x = r.get<std::int32_t>("the grid dims");
    g.dims.y = r.get<std::int32_t>("the grid dims");
    g.dims.z = r.get<std::int32_t>("the grid dims");
    g.voxel_size = r.get<double>("the voxel size");
    g.origin.x = r.get<double>("the origin");
    g.origin.y = r.get<double>("the origin");
    g.origin.z = r.get<double>("the origin");
    const auto ndirs = r.get<std::uint32_t>("the direction count");
    if (ndirs > kMaxDirections) r.fail(std::to_string(ndirs) + " directions (at most 64)");
    std::vector<glm::dvec3> dirs(ndirs);
    for (glm::dvec3& v : dirs) {
        v.x = r.get<double>("a direction");
        v.y = r.get<double>("a direction");
        v.z = r.get<double>("a direction");
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) r.fail("a direction is not finite");
    }
    if (shape) check_shape(name, g, dirs, *shape);
    const auto nfields = r.get<std::uint32_t>("the field count");
    if (nfields > kMaxFields) r.fail(std::to_string(nfields) + " fields (at most 16)");
    // A field holds S per output direction: with none it would hold nothing (an empty field a
    // composition cannot read; fuzz_fgl found its copy of zero bytes from no storage).
    if (nfields > 0 && ndirs == 0) r.fail(std::to_string(nfields) + " fields over no output directions");
    if (nfields > 0) {
        try {
            core::validate_geometry(g, name + ": grid");
        } catch (const core::Error& e) {
            r.fail(e.reason());
        }
    }
    std::vector<NamedField> out;
    for (std::uint32_t f = 0; f < nfields; ++f) {
        const auto len = r.get<std::uint32_t>("a field name's length");
        if (len == 0 || len > kMaxName) r.fail("field name of " + std::to_string(len) + " bytes (1..64)");
        NamedField nf{r.text(len, "a field name"), transport::SourceField()};
        for (const NamedField& seen : out)
            if (seen.name == nf.name) r.fail("field \"" + nf.name + "\" appears twice");
        if (shape && std::find(shape->names.begin(), shape->names.end(), nf.name) == shape->names.end())
            r.fail("field \"" + nf.name + "\" is not one this light has");
        const std::size_t n = g.cell_count() * ndirs;
        if ((r.end - r.at) / sizeof(float) < n)
            r.fail("truncated: field \"" + nf.name + "\" needs " + std::to_string(n) + " floats");
        nf.field.geom = g;
        nf.field.directions = dirs;
        nf.field.data.resize(n);
        std::memcpy(nf.field.data.data(), bytes.data() + r.at, n * sizeof(float));
        check_values(r, nf);
        r.at += n * sizeof(float);
        out.push_back(std::move(nf));
    }
    if (r.at != r.end) r.fail(std::to_string(r.end - r.at) + " unexpected bytes before the checksum");
    return out;
}

std::optional<std::filesystem::path> cache_path(const scene::Scene& s, const CacheOptions& cache,
                                                std::string_view kind) {
    if (!cache.enabled || s.path.empty()) return std::nullopt;
    std::filesystem::path dir = cache.dir.empty() ? s.path.parent_path() : cache.dir;
    if (dir.empty()) dir = ".";  // a scene named relative to the working directory
    return dir / (s.path.stem().string() + "." + std::string(kind) + ".fgl");
}

StaticLight load_or_solve(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& media,
                          const ScenePlan& plan, const CacheOptions& cache,
                          const std::function<void(const std::string&)>& say) {
    StaticLight out;
    const std::vector<glm::dvec3> dirs = transport::output_directions(plan.directions);
    // Over several processes, process 0 alone reads and writes the cache, speaks, and tells the
    // others whether each light is solved (they all take part in a solve).
    const Processes* procs =
        plan.settings.processes && plan.settings.processes->size() > 1 ? plan.settings.processes.get() : nullptr;
    const bool first = !procs || procs->rank() == 0;
    auto agree = [&](bool solve) { return procs ? procs->broadcast(solve ? 1 : 0) != 0 : solve; };
    auto tell = [&](const std::string& m) {
        if (say && first) say(m);
    };
    // Reads the cache file when it is fresh; returns why not otherwise.
    // Reads the cache file when it is fresh and holds this scene's grid and directions;
    // returns why not otherwise. A path that exists but is no regular file (a directory, a
    // FIFO, a device) is refused before any solve: the solve's result could not be kept.
    auto cached = [&](const std::optional<std::filesystem::path>& p, const basis::BakeKey& key,
                      const LightFileShape& shape, std::vector<NamedField>& fields) -> std::string {
        if (!p) return "no cache";
        std::error_code ec;
        const std::filesystem::file_status st = std::filesystem::status(*p, ec);
        if (!std::filesystem::exists(st)) return "no cache file " + p->string();
        if (!std::filesystem::is_regular_file(st))
            throw core::Error(p->string(),
                              "is not a regular file, so the light cache cannot be kept there: remove it "
                              "or point the cache elsewhere");
        try {
            fields = read_light_file(*p, &key, &shape);
        } catch (const core::Error& e) {
            return e.what();
        }
        return {};
    };
    auto store = [&](const std::optional<std::filesystem::path>& p, const basis::BakeKey& key,
                     const std::vector<NamedField>& fields) {
        if (!p || !first) return;
        std::filesystem::create_directories(p->parent_path());
        write_light_file(*p, key, fields);
    };
    const core::GridGeometry& grid = media.lighting.density.geom;
    if (plan.sun) {
        const glm::dvec3 d = s.sun->direction;
        const basis::BakeKey key = sun_key(s, density, plan.settings, d);
        const auto p = cache_path(s, cache, "sun");
        std::vector<NamedField> fields;
        const std::string why = first ? cached(p, key, {grid, dirs, {"single", "multiple"}}, fields) : "";
        if (!agree(!why.empty())) {
            if (first) {
                out.sun = field_of(fields, "");
                tell("sun: read from " + p->string());
            }
        } else {
            core::Stopwatch sw;
            const transport::DirectionalSource unit{d, 1.0};
            out.sun = solve_directional(media, std::span(&unit, 1), dirs, plan.settings);
            tell("sun: solved in " + core::format_seconds(sw.seconds()) + " (" + why + ")");
            store(p, key, light_fields(*out.sun, ""));
        }
        out.sun_direction = d;
    }
    if (plan.sky) {
        const basis::BakeKey key = sky_key(s, density, plan.settings, plan.sky_uniform);
        const auto p = cache_path(s, cache, "sky");
        std::vector<NamedField> fields;
        const LightFileShape shape{grid,
                                   dirs,
                                   {"zenith.single", "zenith.multiple", "horizon.single", "horizon.multiple",
                                    "uniform.single", "uniform.multiple"}};
        const std::string why = first ? cached(p, key, shape, fields) : "";
        SkyField sky;
        const bool solve = agree(!why.empty());
        if (!solve) {
            if (first) {
                sky.zenith = field_of(fields, "zenith.");
                sky.horizon = field_of(fields, "horizon.");
                sky.uniform = field_of(fields, "uniform.");
                tell("sky: read from " + p->string());
            }
        } else {
            core::Stopwatch sw;
            sky = solve_sky(media, plan.sky_uniform, dirs, plan.settings);
            tell("sky: solved in " + core::format_seconds(sw.seconds()) + " (" + why + ")");
            std::vector<NamedField> all = light_fields(sky.zenith, "zenith.");
            for (NamedField& f : light_fields(sky.horizon, "horizon.")) all.push_back(std::move(f));
            for (NamedField& f : light_fields(sky.uniform, "uniform.")) all.push_back(std::move(f));
            store(p, key, all);
        }
        if (first || solve) out.sky = std::move(sky);
    }
    return out;
}

}  // namespace fulgur::sky
