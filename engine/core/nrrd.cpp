// NRRD (http://teem.sourceforge.net/nrrd/format.html), the subset Fulgur reads and writes:
// 3D, float32, raw encoding, little endian, attached data, axis-aligned uniform spacing.
#include "core/core.h"

#include <bit>
#include <charconv>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

namespace fulgur::core {

static_assert(std::endian::native == std::endian::little, "Fulgur's file formats assume a little-endian host");

void write_nrrd(const std::filesystem::path& path, const Grid3<float>& grid, std::string_view content) {
    const GridGeometry& g = grid.geom;
    FULGUR_ASSERT(grid.data.size() == g.cell_count(), "grid data size does not match its dimensions");
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path.string(), "cannot open for writing");
    std::ostringstream h;
    h.precision(17);
    h << "NRRD0004\n"
      << "# Written by Fulgur. Units: metres. Cell-centred samples.\n"
      << "type: float\n"
      << "dimension: 3\n"
      << "space: 3D-right-handed\n"
      << "sizes: " << g.dims.x << ' ' << g.dims.y << ' ' << g.dims.z << '\n'
      << "space directions: (" << g.voxel_size << ",0,0) (0," << g.voxel_size << ",0) (0,0," << g.voxel_size << ")\n"
      << "centers: cell cell cell\n"
      << "kinds: space space space\n"
      // NRRD's space origin is the position of the first sample, i.e. the first voxel centre.
      << "space origin: (" << g.origin.x + 0.5 * g.voxel_size << ',' << g.origin.y + 0.5 * g.voxel_size << ','
      << g.origin.z + 0.5 * g.voxel_size << ")\n";
    if (!content.empty()) {
        std::string c(content);
        for (char& ch : c)
            if (ch == '\n' || ch == '\r') ch = ' ';
        h << "content: " << c << '\n';
    }
    h << "endian: little\n"
      << "encoding: raw\n\n";
    const std::string header = h.str();
    out.write(header.data(), std::streamsize(header.size()));
    out.write(reinterpret_cast<const char*>(grid.data.data()), std::streamsize(grid.data.size() * sizeof(float)));
    if (!out) throw Error(path.string(), "write failed");
}

namespace {

std::string trim(std::string s) {
    const auto b = s.find_first_not_of(" \t\r");
    const auto e = s.find_last_not_of(" \t\r");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

// Parses "(a,b,c)" into three doubles; returns false on any malformed input.
bool parse_vector(std::string_view s, double v[3]) {
    std::string t(s);
    for (char& c : t)
        if (c == '(' || c == ')' || c == ',') c = ' ';
    std::istringstream is(t);
    is >> v[0] >> v[1] >> v[2];
    std::string rest;
    return !is.fail() && !(is >> rest);
}

}  // namespace

Grid3<float> read_nrrd(const std::filesystem::path& path) {
    const std::string file = path.string();
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(file, "cannot open for reading");
    in.seekg(0, std::ios::end);
    const auto file_size = std::uint64_t(in.tellg());
    in.seekg(0);

    std::string line;
    std::uint64_t offset = 0;
    auto where = [&](std::uint64_t at) { return file + " (byte " + std::to_string(at) + ")"; };
    if (!std::getline(in, line) || line.rfind("NRRD000", 0) != 0)
        throw Error(where(0), "not a NRRD file (expected magic 'NRRD000x')");
    offset += line.size() + 1;

    std::map<std::string, std::pair<std::string, std::uint64_t>> fields;
    constexpr std::size_t kMaxHeader = 1 << 16;
    for (;;) {
        const std::uint64_t line_start = offset;
        if (!std::getline(in, line))
            throw Error(where(offset), "header ends before the blank line that starts the data");
        offset += line.size() + 1;
        if (offset > kMaxHeader) throw Error(where(line_start), "header longer than 64 KiB");
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty()) break;
        if (line[0] == '#') continue;
        const auto colon = line.find(": ");
        if (colon == std::string::npos) {
            if (line.find(":=") != std::string::npos) continue;  // key/value pairs are ignored
            throw Error(where(line_start), "malformed header line '" + line + "' (expected 'field: value')");
        }
        fields[trim(line.substr(0, colon))] = {trim(line.substr(colon + 2)), line_start};
    }
    const std::uint64_t data_start = offset;

    auto need = [&](const char* key) -> const std::pair<std::string, std::uint64_t>& {
        auto it = fields.find(key);
        if (it == fields.end()) throw Error(file, std::string("missing header field '") + key + "'");
        return it->second;
    };
    auto expect = [&](const char* key, std::initializer_list<const char*> allowed) {
        const auto& [value, at] = need(key);
        for (const char* a : allowed)
            if (value == a) return;
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        throw Error(where(at), std::string("field '") + key + "' is '" + value + "'; supported: " + list);
    };
    expect("type", {"float", "float32"});
    expect("dimension", {"3"});
    expect("encoding", {"raw"});
    if (fields.count("endian")) expect("endian", {"little"});
    if (fields.count("data file") || fields.count("datafile"))
        throw Error(file, "detached data files are not supported; data must follow the header");

    GridGeometry g;
    {
        const auto& [value, at] = need("sizes");
        std::istringstream is(value);
        long long n[3] = {0, 0, 0};
        is >> n[0] >> n[1] >> n[2];
        std::string rest;
        if (is.fail() || (is >> rest))
            throw Error(where(at), "field 'sizes' must hold three integers, got '" + value + "'");
        for (long long v : n)
            if (v < 1 || v > 4096)
                throw Error(where(at), "field 'sizes': each size must be in [1, 4096], got '" + value + "'");
        g.dims = {int(n[0]), int(n[1]), int(n[2])};
    }
    double spacing = 1.0;
    if (auto it = fields.find("space directions"); it != fields.end()) {
        const auto& [value, at] = it->second;
        std::istringstream is(value);
        std::string tok[3];
        is >> tok[0] >> tok[1] >> tok[2];
        double d[3][3];
        for (int a = 0; a < 3; ++a)
            if (!parse_vector(tok[a], d[a]))
                throw Error(where(at),
                            "field 'space directions' must hold three vectors '(x,y,z)', got '" + value + "'");
        spacing = d[0][0];
        const double tol = 1e-6 * std::fabs(spacing);  // text round-off of the written spacing
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) {
                const double expected = a == b ? spacing : 0.0;
                if (std::fabs(d[a][b] - expected) > tol)
                    throw Error(where(at), "only axis-aligned, isotropic spacing is supported, got '" + value + "'");
            }
    } else if (auto sp = fields.find("spacings"); sp != fields.end()) {
        const auto& [value, at] = sp->second;
        std::istringstream is(value);
        double s[3];
        is >> s[0] >> s[1] >> s[2];
        if (is.fail() || std::fabs(s[0] - s[1]) > 1e-6 * s[0] || std::fabs(s[0] - s[2]) > 1e-6 * s[0])
            throw Error(where(at), "field 'spacings' must hold three equal spacings, got '" + value + "'");
        spacing = s[0];
    }
    if (!std::isfinite(spacing) || !(spacing > 0.0))
        throw Error(file, "voxel spacing must be finite and positive, got " + std::to_string(spacing));
    g.voxel_size = spacing;
    if (auto it = fields.find("space origin"); it != fields.end()) {
        double o[3];
        if (!parse_vector(it->second.first, o))
            throw Error(where(it->second.second),
                        "field 'space origin' must be '(x,y,z)', got '" + it->second.first + "'");
        g.origin = glm::dvec3(o[0], o[1], o[2]) - 0.5 * spacing;
    }
    validate_geometry(g, file);

    const std::uint64_t bytes = std::uint64_t(g.cell_count()) * sizeof(float);
    if (file_size < data_start + bytes)
        throw Error(where(data_start), "data truncated: expected " + std::to_string(bytes) +
                                           " bytes of float32, file has " + std::to_string(file_size - data_start));
    if (file_size > data_start + bytes)
        throw Error(where(data_start + bytes), std::to_string(file_size - data_start - bytes) +
                                                   " unexpected trailing bytes after the float32 data");
    Grid3<float> grid(g);
    in.seekg(std::streamoff(data_start));
    in.read(reinterpret_cast<char*>(grid.data.data()), std::streamsize(bytes));
    if (!in) throw Error(where(data_start), "read failed");
    for (std::size_t i = 0; i < grid.data.size(); ++i)
        if (!std::isfinite(grid.data[i]))
            throw Error(where(data_start + i * sizeof(float)),
                        "non-finite value (NaN or Inf) at voxel " + std::to_string(i));
    return grid;
}

}  // namespace fulgur::core
