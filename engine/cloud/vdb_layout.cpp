// How a .vdb file's grid becomes the engine's density grid, on the grid descriptors alone
// (detail/vdb_layout.h): the choice of grid, its statistics, its transform and the mapping of
// its axes, the density grid's geometry and the load's peak memory. No OpenVDB here: the
// descriptors are the plain GridFacts the reading child sends.
#include "cloud/detail/vdb_layout.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace fulgur::cloud {

namespace detail::vdb {

namespace {

// OpenVDB writes a second grid of an existing name with a suffix after '\x1e' and reads it
// back under the bare name: compare names without it.
std::string bare_name(const std::string& s) { return s.substr(0, s.find('\x1e')); }

// The grid the options ask for, listing every grid in info.grids and setting info.grid and
// info.first_float_grid. OpenVDB lists a file's grids by name. Without a name: the float grid
// "density" (the name Houdini, Blender and EmberGen give it), or else the first float grid by
// name.
const GridFacts& choose_grid(const std::vector<GridFacts>& grids, const std::string& file, const VdbImport& o,
                             VdbInfo& info) {
    const GridFacts* chosen = nullptr;
    for (const GridFacts& g : grids) {
        info.grids.push_back(g.name + " (" + g.value_type + ")");
        if (o.grid.empty() ? g.float_grid && (!chosen || g.name == "density") : !chosen && g.name == o.grid)
            chosen = &g;
    }
    if (!chosen) {
        if (o.grid.empty())
            throw core::Error(file, "no float grid in the file (it holds " + list_grids(info.grids) + ")");
        throw core::Error(file + ": grid " + in_quotes(o.grid),
                          "no such grid (the file holds " + list_grids(info.grids) + ")");
    }
    // OpenVDB reads a grid by name: with two of that name, the statistics of one would size
    // the voxels of the other.
    const std::size_t same = std::size_t(std::count_if(
        grids.begin(), grids.end(), [&](const GridFacts& g) { return bare_name(g.name) == bare_name(chosen->name); }));
    if (same > 1)
        throw core::Error(file, "holds " + std::to_string(same) + " grids named " + in_quotes(chosen->name) +
                                    "; rename one (OpenVDB reads grids by name)");
    info.grid = chosen->name;
    info.first_float_grid = o.grid.empty();
    if (!chosen->float_grid)
        throw core::Error(file + ": grid " + in_quotes(info.grid),
                          "holds " + chosen->value_type + " values; expected a float grid (a scalar density)");
    return *chosen;
}

// The active voxels' box, from the statistics OpenVDB writes with every grid (io::File's
// default): the load is sized before any voxel is read.
Box active_box(const GridFacts& g, const std::string& where) {
    if (!g.has_bbox_min || !g.has_bbox_max || !g.has_count)
        throw core::Error(where,
                          "has no file_bbox_min / file_bbox_max / file_voxel_count metadata (written with grid "
                          "statistics off); save it again with OpenVDB's defaults so its size is known before loading");
    if (g.count <= 0) throw core::Error(where, "has no active voxels: the cloud is empty");
    Box box;
    for (int a = 0; a < 3; ++a) {
        box.min[a] = g.bbox_min[a];
        box.max[a] = g.bbox_max[a];
    }
    if (box.empty()) throw core::Error(where, "has an empty active bounding box (file_bbox_min > file_bbox_max)");
    for (int a = 0; a < 3; ++a) {
        // 2^20 voxels along an axis is far past any cloud (and keeps index arithmetic in int);
        // the memory check of inspect() refuses most boxes well before this.
        const long long n = (long long)box.max[a] - (long long)box.min[a] + 1;
        if (n > (1LL << 20))
            throw core::Error(where, "its active voxels span " + std::to_string(n) + " voxels along axis " +
                                         std::to_string(a) + "; at most 1048576 are read");
    }
    return box;
}

// The transform: linear and axis-aligned, finite, positive scales. Its matrix comes from the
// map's forward application (never inverted: a NaN would make OpenVDB throw from the
// inversion without naming the grid).
void check_transform(const GridFacts& g, const std::string& where) {
    if (!g.linear)
        throw core::Error(where, "has a non-linear (" + g.map_type +
                                     ") transform; resample it onto a linear, axis-aligned grid before importing");
    auto m = [&](int r, int c) { return g.m[r][c]; };
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(m(r, c)))
                throw core::Error(where, "has a transform with a non-finite " +
                                             std::string(r == 3 ? "translation" : "matrix") + " element (" +
                                             std::to_string(r) + "," + std::to_string(c) +
                                             ") = " + core::format_number(m(r, c), 6) + "; refusing it");
    double largest = 0.0;
    for (int r = 0; r < 3; ++r) largest = std::max(largest, std::abs(m(r, r)));
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            // Off-diagonal terms within 1e-9 of the scale are rounding of an axis-aligned
            // transform written through a matrix; anything larger is a rotation or a shear.
            if (r != c && std::abs(m(r, c)) > 1e-9 * largest)
                throw core::Error(where, "has a rotated or sheared transform (matrix element (" + std::to_string(r) +
                                             "," + std::to_string(c) + ") = " + core::format_number(m(r, c), 6) +
                                             "); resample it onto an axis-aligned grid before importing");
    for (int a = 0; a < 3; ++a)
        if (!(m(a, a) > 0.0))
            throw core::Error(where, "has a mirrored or degenerate transform (scale " +
                                         core::format_number(m(a, a), 6) + " along axis " + std::to_string(a) +
                                         "); expected positive scales");
}

// File axes -> engine axes (y-up: engine x = x, engine y = -z, engine z = y), and the file's
// box in engine coordinates: info.source_dims, info.source_voxel, L.source_origin. The
// transform is checked (check_transform).
void map_axes(const GridFacts& g, const VdbImport& o, Layout& L) {
    auto m = [&](int r, int c) { return g.m[r][c]; };
    const double t[3] = {m(3, 0), m(3, 1), m(3, 2)};
    if (o.y_up) {
        L.src_axis[1] = 2;
        L.src_axis[2] = 1;
        L.flip[1] = true;
    }
    const double smallest_file = std::min({m(0, 0), m(1, 1), m(2, 2)});
    const double metres = o.voxel_size > 0.0 ? o.voxel_size / smallest_file : o.scale;
    int dims[3];
    double spacing[3], lower[3];
    for (int a = 0; a < 3; ++a) {
        const int s = L.src_axis[a];
        const double h = m(s, s) * metres;
        dims[a] = L.bbox.max[s] - L.bbox.min[s] + 1;
        spacing[a] = h;
        // Voxel i of the file is centred on t + i h: its box is [t + (i - 1/2) h, t + (i + 1/2) h].
        const double lo = (t[s] + (double(L.bbox.min[s]) - 0.5) * m(s, s)) * metres;
        const double hi = (t[s] + (double(L.bbox.max[s]) + 0.5) * m(s, s)) * metres;
        lower[a] = (L.flip[a] ? -hi : lo) + o.offset[a];
    }
    L.info.source_dims = {dims[0], dims[1], dims[2]};
    L.info.source_voxel = {spacing[0], spacing[1], spacing[2]};
    L.source_origin = {lower[0], lower[1], lower[2]};
}

// The density grid over the file's box (map_axes ran): its voxel size (the option, or the
// file's finest spacing), origin and dimensions, checked against the engine's limits.
void density_geometry(const VdbImport& o, const std::string& where, Layout& L) {
    const VdbInfo& info = L.info;
    core::GridGeometry& g = L.info.density;
    g.voxel_size = o.density_voxel_size > 0.0
                       ? o.density_voxel_size
                       : std::min({info.source_voxel.x, info.source_voxel.y, info.source_voxel.z});
    g.origin = L.source_origin;
    const int dims[3] = {info.source_dims.x, info.source_dims.y, info.source_dims.z};
    int out[3];
    for (int a = 0; a < 3; ++a) {
        // The density grid covers the file's box; 1e-9 keeps an exact multiple from growing a
        // voxel through rounding. Clamped past 2^30 so validate_geometry names the size.
        const double n = std::ceil(double(dims[a]) * info.source_voxel[a] / g.voxel_size - 1e-9);
        out[a] = int(std::clamp(n, 1.0, double(1 << 30)));
    }
    g.dims = {out[0], out[1], out[2]};
    core::validate_geometry(g, where + " (as a density grid)");
}

// Peak memory of load() (density_geometry ran): the sparse tree as OpenVDB holds it (in the
// reading process), the dense copy of the file's box, the two intermediate passes of the
// separable filter and the density.
void estimate_memory(const GridFacts& chosen, Layout& L) {
    VdbInfo& info = L.info;
    const core::Int3 dims = info.source_dims, out = info.density.dims;
    const double tree =
        chosen.has_mem && chosen.mem >= 0 ? double(chosen.mem) : double(info.active_voxels) * 4.0 * 1.25;
    const double src = double(dims.x) * double(dims.y) * double(dims.z);
    const double pass1 = double(out.x) * double(dims.y) * double(dims.z);
    const double pass2 = double(out.x) * double(out.y) * double(dims.z);
    const double bytes = tree + 4.0 * (src + pass1 + pass2 + double(info.density.cell_count()));
    auto saturate = [](double b) { return b >= 1.8e19 ? std::numeric_limits<std::uint64_t>::max() : std::uint64_t(b); };
    info.load_bytes = saturate(bytes);
    L.tree_bytes = saturate(tree);
}

}  // namespace

void check_options(const VdbImport& o) {
    FULGUR_ASSERT(o.scale > 0.0 && o.voxel_size >= 0.0 && o.density_voxel_size >= 0.0 && o.density_scale > 0.0,
                  "VdbImport sizes must be positive (0: default)");
}

Layout inspect(const std::vector<GridFacts>& grids, const std::filesystem::path& path, const VdbImport& o) {
    check_options(o);
    Layout L;
    const std::string file = path.string();
    const GridFacts& chosen = choose_grid(grids, file, o, L.info);
    const std::string where = file + ": grid " + in_quotes(L.info.grid);
    L.bbox = active_box(chosen, where);
    L.info.active_voxels = std::uint64_t(chosen.count);
    check_transform(chosen, where);
    map_axes(chosen, o, L);
    density_geometry(o, where, L);
    estimate_memory(chosen, L);
    return L;
}

std::string dims_text(core::Int3 d) {
    return std::to_string(d.x) + " x " + std::to_string(d.y) + " x " + std::to_string(d.z);
}

std::string list_grids(const std::vector<std::string>& grids) {
    if (grids.empty()) return "no grid";
    std::string s;
    for (std::size_t i = 0; i < grids.size(); ++i) {
        if (s.size() > 300) return s + ", ... (" + std::to_string(grids.size()) + " grids)";
        s += (s.empty() ? "" : ", ") + grids[i];
    }
    return s;
}

}  // namespace detail::vdb

std::string VdbInfo::describe() const {
    using detail::vdb::dims_text;
    using detail::vdb::in_quotes;
    std::ostringstream o;
    o << "grid " << in_quotes(grid)
      << (!first_float_grid   ? " (named"
          : grid == "density" ? " (no grid named: the float grid \"density\""
                              : " (no grid named and none called \"density\": the first float grid by name")
      << "; the file holds " << detail::vdb::list_grids(grids) << "): " << dims_text(source_dims) << " file voxels of "
      << core::format_number(source_voxel.x, 4) << " x " << core::format_number(source_voxel.y, 4) << " x "
      << core::format_number(source_voxel.z, 4) << " m (" << active_voxels << " active), ";
    const bool same = source_voxel.x == density.voxel_size && source_voxel.y == density.voxel_size &&
                      source_voxel.z == density.voxel_size;
    o << (same ? "copied onto " : "box-filtered onto ") << dims_text(density.dims) << " density voxels of "
      << core::format_number(density.voxel_size, 4) << " m";
    return o.str();
}

}  // namespace fulgur::cloud
