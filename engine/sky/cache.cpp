// Solving once: the keys of the sun's and the sky's solves, the light file, and
// load_or_solve (sky.h, docs/sky.md "The cache").
#include "sky/sky.h"

#include <zlib.h>
#include <glm/geometric.hpp>

#include <cstring>
#include <fstream>
#include <sstream>

namespace fulgur::sky {

namespace {

// Bump when a solve's algorithm changes what it writes for the same key (forces a new solve).
constexpr int kSkyAlgorithm = 1;
constexpr char kMagic[8] = {'F', 'G', 'L', 'I', 'G', 'H', 'T', '1'};
constexpr std::uint32_t kVersion = 1;
constexpr std::uint32_t kMaxDirections = 64, kMaxFields = 16, kMaxName = 64;
constexpr std::uint32_t kMaxDescription = 1u << 20;

std::string settings_lines(const SolveSettings& st) {
    std::ostringstream d;
    d << "sky.algorithm=" << kSkyAlgorithm << "\n";
    d << "sky.method=" << to_string(st.method) << "\n";
    d << "sky.single=" << st.single << "\n";
    d << "sky.multiple=" << st.multiple << "\n";
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
    d << bake::scene_key(s, density).description << settings_lines(settings);
    d << "sky.light=sun\n";
    d << "sky.sun.direction=" << core::format_number(direction.x, 17) << "," << core::format_number(direction.y, 17)
      << "," << core::format_number(direction.z, 17) << "\n";
    return basis::BakeKey::from_description(d.str());
}

basis::BakeKey sky_key(const scene::Scene& s, const core::Grid3<float>& density, const SolveSettings& settings,
                       bool uniform) {
    std::ostringstream d;
    d << bake::scene_key(s, density).description << settings_lines(settings);
    d << "sky.light=dome\n";
    d << "sky.dome.uniform=" << uniform << "\n";
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
    // Atomically: a partial file never replaces a good one.
    std::filesystem::path tmp = path;
    tmp += ".tmp";
    {
        std::ofstream o(tmp, std::ios::binary | std::ios::trunc);
        if (!o) throw core::Error(tmp.string(), "cannot open for writing");
        o.write(out.data(), std::streamsize(out.size()));
        if (!o) throw core::Error(tmp.string(), "write failed (disk full?)");
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw core::Error(path.string(), "cannot rename " + tmp.string() + " into place: " + ec.message());
}

std::vector<NamedField> read_light_file(const std::filesystem::path& path, const basis::BakeKey* expected) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw core::Error(path.string(), "cannot open light file");
    std::ostringstream buf;
    buf << in.rdbuf();
    const std::string bytes = buf.str();
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
    const auto nfields = r.get<std::uint32_t>("the field count");
    if (nfields > kMaxFields) r.fail(std::to_string(nfields) + " fields (at most 16)");
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
        const std::size_t n = g.cell_count() * ndirs;
        if ((r.end - r.at) / sizeof(float) < n)
            r.fail("truncated: field \"" + nf.name + "\" needs " + std::to_string(n) + " floats");
        nf.field.geom = g;
        nf.field.directions = dirs;
        nf.field.data.resize(n);
        std::memcpy(nf.field.data.data(), bytes.data() + r.at, n * sizeof(float));
        for (std::size_t i = 0; i < n; ++i)
            if (!std::isfinite(nf.field.data[i])) {
                r.at += i * sizeof(float);
                r.fail("field \"" + nf.name + "\": value " + std::to_string(i) + " is not finite");
            }
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
    auto tell = [&](const std::string& m) {
        if (say) say(m);
    };
    // Reads the cache file when it is fresh; returns why not otherwise.
    auto cached = [&](const std::optional<std::filesystem::path>& p, const basis::BakeKey& key,
                      std::vector<NamedField>& fields) -> std::string {
        if (!p) return "no cache";
        std::error_code ec;
        if (!std::filesystem::exists(*p, ec)) return "no cache file " + p->string();
        try {
            fields = read_light_file(*p, &key);
        } catch (const core::Error& e) {
            return e.what();
        }
        return {};
    };
    auto store = [&](const std::optional<std::filesystem::path>& p, const basis::BakeKey& key,
                     const std::vector<NamedField>& fields) {
        if (!p) return;
        std::filesystem::create_directories(p->parent_path());
        write_light_file(*p, key, fields);
    };
    if (plan.sun) {
        const glm::dvec3 d = s.sun->direction;
        const basis::BakeKey key = sun_key(s, density, plan.settings, d);
        const auto p = cache_path(s, cache, "sun");
        std::vector<NamedField> fields;
        const std::string why = cached(p, key, fields);
        if (why.empty()) {
            out.sun = field_of(fields, "");
            tell("sun: read from " + p->string());
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
        const std::string why = cached(p, key, fields);
        SkyField sky;
        if (why.empty()) {
            sky.zenith = field_of(fields, "zenith.");
            sky.horizon = field_of(fields, "horizon.");
            sky.uniform = field_of(fields, "uniform.");
            tell("sky: read from " + p->string());
        } else {
            core::Stopwatch sw;
            sky = solve_sky(media, plan.sky_uniform, dirs, plan.settings);
            tell("sky: solved in " + core::format_seconds(sw.seconds()) + " (" + why + ")");
            std::vector<NamedField> all = light_fields(sky.zenith, "zenith.");
            for (NamedField& f : light_fields(sky.horizon, "horizon.")) all.push_back(std::move(f));
            for (NamedField& f : light_fields(sky.uniform, "uniform.")) all.push_back(std::move(f));
            store(p, key, all);
        }
        out.sky = std::move(sky);
    }
    return out;
}

}  // namespace fulgur::sky
