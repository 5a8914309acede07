// NRRD (http://teem.sourceforge.net/nrrd/format.html), the subset Fulgur reads and writes:
// 3D, float32, raw encoding, little endian, attached data, axis-aligned uniform spacing.
#include "core/core.h"

#include <algorithm>
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
    validate_geometry(g, path.string());
    check_finite(grid, path.string());
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
    AtomicFile out(path);
    out.write(h.str());
    out.write(grid.data.data(), grid.data.size() * sizeof(float));
    out.commit();
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

// The header is at most 64 KiB.
constexpr std::size_t kMaxHeader = 1 << 16;

// The first 64 KiB of the file (or the whole file), where the header lines are parsed from, so
// a file without newlines costs 64 KiB, not its size.
std::string read_head(const std::filesystem::path& path, const std::string& file, std::uint64_t file_size) {
    std::string head;
    {
        std::ifstream in(path, std::ios::binary);
        if (!in) throw Error(file, "cannot open for reading");
        head.resize(std::size_t(std::min<std::uint64_t>(file_size, kMaxHeader)));
        in.read(head.data(), std::streamsize(head.size()));
        if (std::uint64_t(in.gcount()) != head.size()) throw Error(file, "read failed");
    }
    return head;
}

// The header's fields (value and the byte offset of its line, by field name), with errors
// naming the file and the byte.
struct HeaderFields {
    std::string file;
    std::map<std::string, std::pair<std::string, std::uint64_t>> fields;

    std::string where(std::uint64_t at) const { return file + " (byte " + std::to_string(at) + ")"; }

    const std::pair<std::string, std::uint64_t>& need(const char* key) const {
        auto it = fields.find(key);
        if (it == fields.end()) throw Error(file, std::string("missing header field '") + key + "'");
        return it->second;
    }

    void expect(const char* key, std::initializer_list<const char*> allowed) const {
        const auto& [value, at] = need(key);
        for (const char* a : allowed)
            if (value == a) return;
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        throw Error(where(at), std::string("field '") + key + "' is '" + value + "'; supported: " + list);
    }
};

// Checks the magic and reads the header lines up to the blank line that starts the data
// into h.fields (comments and key/value pairs skipped); returns the data offset.
std::uint64_t parse_header_lines(const std::string& head, std::uint64_t file_size, HeaderFields& h) {
    std::size_t offset = 0;
    // One header line (without its '\n'); false when the buffer ends before a newline.
    auto next_line = [&](std::string& line) {
        const std::size_t nl = head.find('\n', offset);
        if (nl == std::string::npos) return false;
        line = head.substr(offset, nl - offset);
        offset = nl + 1;
        return true;
    };
    std::string line;
    if (!next_line(line) || line.rfind("NRRD000", 0) != 0)
        throw Error(h.where(0), "not a NRRD file (expected magic 'NRRD000x')");

    for (;;) {
        const std::uint64_t line_start = offset;
        if (!next_line(line))
            throw Error(h.where(offset), head.size() == kMaxHeader && file_size > kMaxHeader
                                             ? "header longer than 64 KiB"
                                             : "header ends before the blank line that starts the data");
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty()) break;
        if (line[0] == '#') continue;
        if (line.find('\0') != std::string::npos) throw Error(h.where(line_start), "NUL byte in a header line");
        const auto colon = line.find(": ");
        if (colon == std::string::npos) {
            if (line.find(":=") != std::string::npos) continue;  // key/value pairs are ignored
            throw Error(h.where(line_start), "malformed header line '" + line + "' (expected 'field: value')");
        }
        h.fields[trim(line.substr(0, colon))] = {trim(line.substr(colon + 2)), line_start};
    }
    return offset;
}

// The field 'sizes': three sizes in [1, 4096].
Int3 parse_sizes(const HeaderFields& h) {
    const auto& [value, at] = h.need("sizes");
    std::istringstream is(value);
    long long n[3] = {0, 0, 0};
    is >> n[0] >> n[1] >> n[2];
    std::string rest;
    if (is.fail() || (is >> rest))
        throw Error(h.where(at), "field 'sizes' must hold three integers, got '" + value + "'");
    for (long long v : n)
        if (v < 1 || v > 4096)
            throw Error(h.where(at), "field 'sizes': each size must be in [1, 4096], got '" + value + "'");
    return {int(n[0]), int(n[1]), int(n[2])};
}

// The voxel spacing from 'space directions' (axis-aligned and isotropic) or 'spacings' (three
// equal), 1 without either; within [kMinVoxelSize, kMaxVoxelSize].
double parse_spacing(const HeaderFields& h) {
    double spacing = 1.0;
    std::uint64_t spacing_at = 0;
    if (auto it = h.fields.find("space directions"); it != h.fields.end()) {
        const auto& [value, at] = it->second;
        spacing_at = at;
        std::istringstream is(value);
        std::string tok[3];
        is >> tok[0] >> tok[1] >> tok[2];
        double d[3][3];
        for (int a = 0; a < 3; ++a)
            if (!parse_vector(tok[a], d[a]))
                throw Error(h.where(at),
                            "field 'space directions' must hold three vectors '(x,y,z)', got '" + value + "'");
        spacing = d[0][0];
        const double tol = 1e-6 * std::fabs(spacing);  // text round-off of the written spacing
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) {
                const double expected = a == b ? spacing : 0.0;
                if (!(std::fabs(d[a][b] - expected) <= tol))
                    throw Error(h.where(at), "only axis-aligned, isotropic spacing is supported, got '" + value + "'");
            }
    } else if (auto sp = h.fields.find("spacings"); sp != h.fields.end()) {
        const auto& [value, at] = sp->second;
        spacing_at = at;
        std::istringstream is(value);
        double s[3];
        is >> s[0] >> s[1] >> s[2];
        if (is.fail() || !(std::fabs(s[0] - s[1]) <= 1e-6 * s[0]) || !(std::fabs(s[0] - s[2]) <= 1e-6 * s[0]))
            throw Error(h.where(at), "field 'spacings' must hold three equal spacings, got '" + value + "'");
        spacing = s[0];
    }
    if (!(spacing >= kMinVoxelSize && spacing <= kMaxVoxelSize))
        throw Error(h.where(spacing_at), "voxel spacing must be in [" + format_number(kMinVoxelSize) + ", " +
                                             format_number(kMaxVoxelSize) + "] m, got " + format_number(spacing, 17));
    return spacing;
}

}  // namespace

NrrdHeader read_nrrd_header(const std::filesystem::path& path, std::uint64_t max_bytes) {
    HeaderFields h{path.string(), {}};
    const std::string& file = h.file;
    NrrdHeader out;
    out.file_size = check_readable_file(path, max_bytes, "NRRD");
    const std::string head = read_head(path, file, out.file_size);
    out.data_offset = parse_header_lines(head, out.file_size, h);

    h.expect("type", {"float", "float32"});
    h.expect("dimension", {"3"});
    h.expect("encoding", {"raw"});
    if (h.fields.count("endian")) h.expect("endian", {"little"});
    if (h.fields.count("data file") || h.fields.count("datafile"))
        throw Error(file, "detached data files are not supported; data must follow the header");

    GridGeometry& g = out.geom;
    g.dims = parse_sizes(h);
    const double spacing = parse_spacing(h);
    g.voxel_size = spacing;
    if (auto it = h.fields.find("space origin"); it != h.fields.end()) {
        double o[3];
        if (!parse_vector(it->second.first, o))
            throw Error(h.where(it->second.second),
                        "field 'space origin' must be '(x,y,z)', got '" + it->second.first + "'");
        g.origin = glm::dvec3(o[0], o[1], o[2]) - 0.5 * spacing;
    }
    validate_geometry(g, file);

    const std::uint64_t bytes = std::uint64_t(g.cell_count()) * sizeof(float);
    if (out.file_size < out.data_offset + bytes)
        throw Error(h.where(out.data_offset), "data truncated: expected " + std::to_string(bytes) +
                                                  " bytes of float32, file has " +
                                                  std::to_string(out.file_size - out.data_offset));
    if (out.file_size > out.data_offset + bytes)
        throw Error(h.where(out.data_offset + bytes), std::to_string(out.file_size - out.data_offset - bytes) +
                                                          " unexpected trailing bytes after the float32 data");
    return out;
}

Grid3<float> read_nrrd(const std::filesystem::path& path, std::uint64_t max_bytes) {
    const NrrdHeader h = read_nrrd_header(path, max_bytes);
    const std::string file = path.string();
    auto where = [&](std::uint64_t at) { return file + " (byte " + std::to_string(at) + ")"; };
    const std::uint64_t bytes = std::uint64_t(h.geom.cell_count()) * sizeof(float);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(file, "cannot open for reading");
    Grid3<float> grid(h.geom);
    in.seekg(std::streamoff(h.data_offset));
    in.read(reinterpret_cast<char*>(grid.data.data()), std::streamsize(bytes));
    if (!in || std::uint64_t(in.gcount()) != bytes) throw Error(where(h.data_offset), "read failed");
    for (std::size_t i = 0; i < grid.data.size(); ++i)
        if (!std::isfinite(grid.data[i]))
            throw Error(where(h.data_offset + i * sizeof(float)),
                        "non-finite value (NaN or Inf) at voxel " + std::to_string(i));
    return grid;
}

}  // namespace fulgur::core
