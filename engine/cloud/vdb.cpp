// OpenVDB import (a float grid -> the engine's density grid, box-filtered) and export (dense
// grids -> a .vdb with their world transforms and metadata). The only file that includes
// OpenVDB: cloud.h names none of its types.
#include "cloud/cloud.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>

namespace fulgur::cloud {

namespace {

void initialize_openvdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

std::string dims_text(core::Int3 d) {
    return std::to_string(d.x) + " x " + std::to_string(d.y) + " x " + std::to_string(d.z);
}

// "density (float), vel (vec3s)"
std::string list_grids(const std::vector<std::string>& grids) {
    if (grids.empty()) return "no grid";
    std::string s;
    for (const std::string& g : grids) s += (s.empty() ? "" : ", ") + g;
    return s;
}

// Runs `f`, turning OpenVDB's exceptions (a truncated or foreign file, an unknown grid type,
// a failed write) into core::Error naming the file; `what` says what failed.
template <class F>
auto guarded(const std::filesystem::path& path, const char* what, F&& f) {
    try {
        return f();
    } catch (const openvdb::Exception& e) {
        throw core::Error(path.string(), std::string(what) + " (OpenVDB: " + e.what() + ")");
    }
}

// The open file's grid descriptors (metadata and transforms, no voxels).
struct OpenFile {
    openvdb::io::File file;
    openvdb::GridPtrVecPtr grids;
    explicit OpenFile(const std::filesystem::path& path) : file(path.string()) {
        core::check_readable_file(path, kMaxVdbFileBytes, "OpenVDB");
        guarded(path, "not a readable OpenVDB file", [&] {
            file.open(/*delayLoad=*/false);  // no memory-mapped leaves: every voxel is read once, here
            grids = file.readAllGridMetadata();
        });
    }
    ~OpenFile() {
        if (file.isOpen()) file.close();
    }
};

// io::Archive's seekable write into any stream (io::File writes it only to a path, io::Stream
// only without grid offsets): a file with offsets lets readers take its descriptors and
// statistics without reading the voxels, as inspect_vdb does.
class SeekableArchive : public openvdb::io::Archive {
public:
    void write_to(std::ostream& os, const openvdb::GridCPtrVec& grids, const openvdb::MetaMap& meta) const {
        openvdb::io::Archive::write(os, grids, /*seekable=*/true, meta);
    }
};

// What inspect() learns, with the OpenVDB-side numbers load() needs.
struct Layout {
    VdbInfo info;
    openvdb::CoordBBox bbox;               // the file's active-voxel box (index space)
    int src_axis[3] = {0, 1, 2};           // engine axis a reads file axis src_axis[a] ...
    bool flip[3] = {false, false, false};  // ... reversed (y-up: the engine's y is the file's -z)
    glm::dvec3 source_origin{0.0};         // engine coordinates of the box's lower corner, metres
};

Layout inspect(OpenFile& f, const std::filesystem::path& path, const VdbImport& o) {
    FULGUR_ASSERT(o.scale > 0.0 && o.voxel_size >= 0.0 && o.density_voxel_size >= 0.0 && o.density_scale > 0.0,
                  "VdbImport sizes must be positive (0: default)");
    Layout L;
    VdbInfo& info = L.info;
    // OpenVDB lists a file's grids by name. Without a name: the float grid "density" (the
    // name Houdini, Blender and EmberGen give it), or else the first float grid by name.
    openvdb::GridBase::Ptr chosen;
    for (const openvdb::GridBase::Ptr& g : *f.grids) {
        info.grids.push_back(g->getName() + " (" + g->valueType() + ")");
        if (o.grid.empty() ? g->isType<openvdb::FloatGrid>() && (!chosen || g->getName() == "density")
                           : !chosen && g->getName() == o.grid)
            chosen = g;
    }
    const std::string file = path.string();
    if (!chosen) {
        if (o.grid.empty())
            throw core::Error(file, "no float grid in the file (it holds " + list_grids(info.grids) + ")");
        throw core::Error(file + ": grid " + in_quotes(o.grid),
                          "no such grid (the file holds " + list_grids(info.grids) + ")");
    }
    info.grid = chosen->getName();
    info.first_float_grid = o.grid.empty();
    const std::string where = file + ": grid " + in_quotes(info.grid);
    if (!chosen->isType<openvdb::FloatGrid>())
        throw core::Error(where, "holds " + chosen->valueType() + " values; expected a float grid (a scalar density)");

    // The active voxels' box and count, from the statistics OpenVDB writes with every grid
    // (io::File's default): the load is sized before any voxel is read.
    const auto bmin = chosen->getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MIN);
    const auto bmax = chosen->getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MAX);
    const auto count = chosen->getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_VOXEL_COUNT);
    const auto mem = chosen->getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_MEM_BYTES);
    if (!bmin || !bmax || !count)
        throw core::Error(where,
                          "has no file_bbox_min / file_bbox_max / file_voxel_count metadata (written with grid "
                          "statistics off); save it again with OpenVDB's defaults so its size is known before loading");
    if (count->value() <= 0) throw core::Error(where, "has no active voxels: the cloud is empty");
    L.bbox = openvdb::CoordBBox(openvdb::Coord(bmin->value()), openvdb::Coord(bmax->value()));
    if (L.bbox.empty()) throw core::Error(where, "has an empty active bounding box (file_bbox_min > file_bbox_max)");
    for (int a = 0; a < 3; ++a) {
        // 2^20 voxels along an axis is far past any cloud (and keeps index arithmetic in int);
        // the memory check below refuses most boxes well before this.
        const long long n = (long long)L.bbox.max()[a] - (long long)L.bbox.min()[a] + 1;
        if (n > (1LL << 20))
            throw core::Error(where, "its active voxels span " + std::to_string(n) + " voxels along axis " +
                                         std::to_string(a) + "; at most 1048576 are read");
    }
    info.active_voxels = std::uint64_t(count->value());

    // The transform: linear and axis-aligned, positive scales.
    const openvdb::math::Transform& xf = chosen->transform();
    if (!xf.isLinear())
        throw core::Error(where, "has a non-linear (" + xf.mapType() +
                                     ") transform; resample it onto a linear, axis-aligned grid before importing");
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getConstMat4();
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
        if (!(m(a, a) > 0.0) || !std::isfinite(m(a, a)))
            throw core::Error(where, "has a mirrored or degenerate transform (scale " +
                                         core::format_number(m(a, a), 6) + " along axis " + std::to_string(a) +
                                         "); expected positive scales");
    const openvdb::Vec3d t = m.getTranslation();

    // File axes -> engine axes (y-up: engine x = x, engine y = -z, engine z = y).
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
        dims[a] = L.bbox.max()[s] - L.bbox.min()[s] + 1;
        spacing[a] = h;
        // Voxel i of the file is centred on t + i h: its box is [t + (i - 1/2) h, t + (i + 1/2) h].
        const double lo = (t[s] + (double(L.bbox.min()[s]) - 0.5) * m(s, s)) * metres;
        const double hi = (t[s] + (double(L.bbox.max()[s]) + 0.5) * m(s, s)) * metres;
        lower[a] = (L.flip[a] ? -hi : lo) + o.offset[a];
    }
    info.source_dims = {dims[0], dims[1], dims[2]};
    info.source_voxel = {spacing[0], spacing[1], spacing[2]};
    L.source_origin = {lower[0], lower[1], lower[2]};

    core::GridGeometry& g = info.density;
    g.voxel_size = o.density_voxel_size > 0.0 ? o.density_voxel_size : std::min({spacing[0], spacing[1], spacing[2]});
    g.origin = L.source_origin;
    int out[3];
    for (int a = 0; a < 3; ++a) {
        // The density grid covers the file's box; 1e-9 keeps an exact multiple from growing a
        // voxel through rounding. Clamped past 2^30 so validate_geometry names the size.
        const double n = std::ceil(double(dims[a]) * spacing[a] / g.voxel_size - 1e-9);
        out[a] = int(std::clamp(n, 1.0, double(1 << 30)));
    }
    g.dims = {out[0], out[1], out[2]};
    core::validate_geometry(g, where + " (as a density grid)");

    // Peak memory of load(): the sparse tree as OpenVDB holds it, the dense copy of the file's
    // box, the two intermediate passes of the separable filter and the density.
    const double tree = mem ? double(mem->value()) : double(info.active_voxels) * 4.0 * 1.25;
    const double src = double(dims[0]) * double(dims[1]) * double(dims[2]);
    const double pass1 = double(out[0]) * double(dims[1]) * double(dims[2]);
    const double pass2 = double(out[0]) * double(out[1]) * double(dims[2]);
    const double bytes = tree + 4.0 * (src + pass1 + pass2 + double(g.cell_count()));
    info.load_bytes = bytes >= 1.8e19 ? std::numeric_limits<std::uint64_t>::max() : std::uint64_t(bytes);
    return L;
}

// Box-filter weights along one axis: target cell t covers [t r, (t + 1) r] in source cells
// (r = target / source spacing, both boxes starting at the same corner); its weight on
// source cell s is the overlap length over r. r = 1 gives weight exactly 1 on s = t.
struct AxisWeights {
    std::vector<int> first;  // first source cell of each target cell
    std::vector<std::vector<double>> weights;
};

AxisWeights axis_weights(int n_src, int n_out, double r) {
    AxisWeights w;
    w.first.resize(std::size_t(n_out));
    w.weights.resize(std::size_t(n_out));
    for (int t = 0; t < n_out; ++t) {
        const double u0 = double(t) * r, u1 = double(t + 1) * r;
        const int s0 = std::clamp(int(std::floor(u0)), 0, n_src), s1 = std::clamp(int(std::ceil(u1)), 0, n_src);
        w.first[std::size_t(t)] = s0;
        for (int s = s0; s < s1; ++s)
            w.weights[std::size_t(t)].push_back((std::min(u1, double(s + 1)) - std::max(u0, double(s))) / r);
    }
    return w;
}

// One pass of the separable box filter along `axis` (x fastest layout): dims[axis] becomes n_out.
std::vector<float> resample_axis(const std::vector<float>& in, int dims[3], int axis, int n_out, double r) {
    const AxisWeights w = axis_weights(dims[axis], n_out, r);
    int od[3] = {dims[0], dims[1], dims[2]};
    od[axis] = n_out;
    std::vector<float> out(std::size_t{1} * std::size_t(od[0]) * std::size_t(od[1]) * std::size_t(od[2]));
    const std::size_t in_stride = axis == 0 ? 1 : axis == 1 ? std::size_t(dims[0]) : std::size_t(dims[0]) * dims[1];
    const std::size_t out_stride = axis == 0 ? 1 : axis == 1 ? std::size_t(od[0]) : std::size_t(od[0]) * od[1];
    // Lines along `axis`: indexed by the other two coordinates (a, b).
    const int oa = axis == 0 ? 1 : 0, ob = axis == 2 ? 1 : 2;
    const long long lines = (long long)dims[oa] * dims[ob];
#pragma omp parallel for schedule(static)
    for (long long line = 0; line < lines; ++line) {
        int c[3] = {0, 0, 0};
        c[oa] = int(line % dims[oa]);
        c[ob] = int(line / dims[oa]);
        const std::size_t in0 =
            std::size_t(c[0]) + std::size_t(dims[0]) * (std::size_t(c[1]) + std::size_t(dims[1]) * c[2]);
        const std::size_t out0 =
            std::size_t(c[0]) + std::size_t(od[0]) * (std::size_t(c[1]) + std::size_t(od[1]) * c[2]);
        for (int t = 0; t < n_out; ++t) {
            double sum = 0.0;
            const std::vector<double>& ws = w.weights[std::size_t(t)];
            for (std::size_t k = 0; k < ws.size(); ++k)
                sum += ws[k] * double(in[in0 + std::size_t(w.first[std::size_t(t)] + int(k)) * in_stride]);
            out[out0 + std::size_t(t) * out_stride] = float(sum);
        }
    }
    dims[axis] = n_out;
    return out;
}

}  // namespace

std::string VdbInfo::describe() const {
    std::ostringstream o;
    o << "grid " << in_quotes(grid)
      << (!first_float_grid   ? " (named"
          : grid == "density" ? " (no grid named: the float grid \"density\""
                              : " (no grid named and none called \"density\": the first float grid by name")
      << "; the file holds " << list_grids(grids) << "): " << dims_text(source_dims) << " file voxels of "
      << core::format_number(source_voxel.x, 4) << " x " << core::format_number(source_voxel.y, 4) << " x "
      << core::format_number(source_voxel.z, 4) << " m (" << active_voxels << " active), ";
    const bool same = source_voxel.x == density.voxel_size && source_voxel.y == density.voxel_size &&
                      source_voxel.z == density.voxel_size;
    o << (same ? "copied onto " : "box-filtered onto ") << dims_text(density.dims) << " density voxels of "
      << core::format_number(density.voxel_size, 4) << " m";
    return o.str();
}

VdbInfo inspect_vdb(const std::filesystem::path& path, const VdbImport& options) {
    initialize_openvdb();
    OpenFile f(path);
    return inspect(f, path, options).info;
}

core::Grid3<float> load_vdb(const std::filesystem::path& path, const VdbImport& options) {
    initialize_openvdb();
    OpenFile f(path);
    const Layout L = inspect(f, path, options);
    const VdbInfo& info = L.info;
    const std::string where = path.string() + ": grid " + in_quotes(info.grid);
    if (info.load_bytes > options.max_bytes)
        throw core::Error(where, "loading it would need about " + core::format_bytes(double(info.load_bytes)) + " (" +
                                     dims_text(info.source_dims) + " file voxels onto " + dims_text(info.density.dims) +
                                     "), over the limit of " + core::format_bytes(double(options.max_bytes)));

    const openvdb::FloatGrid::Ptr grid = guarded(path, "its grid could not be read", [&] {
        return openvdb::gridPtrCast<openvdb::FloatGrid>(f.file.readGrid(info.grid));
    });
    FULGUR_ASSERT(grid, "inspect() checked the grid's type");
    if (grid->background() != 0.0f)
        throw core::Error(where, "has background " + core::format_number(grid->background(), 6) +
                                     "; a density grid's background (its value outside the active voxels) must be 0");
    // The statistics sized the load: a tree reaching beyond them is refused, not allocated.
    const openvdb::CoordBBox actual = grid->evalActiveVoxelBoundingBox();
    if (!actual.empty() && !L.bbox.isInside(actual)) {
        std::ostringstream m;
        m << "its active voxels span " << actual << ", beyond the box its metadata states (" << L.bbox
          << "); refusing to load a file whose size was misstated";
        throw core::Error(where, m.str());
    }

    // The file's box as a dense array in the engine's axis order (tile values included: the
    // accessor returns a tile's value for each of its voxels).
    int dims[3] = {info.source_dims.x, info.source_dims.y, info.source_dims.z};
    std::vector<float> dense(std::size_t{1} * std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(dims[2]));
    const openvdb::Coord lo = L.bbox.min(), hi = L.bbox.max();
    const float gain = float(options.density_scale);
#pragma omp parallel
    {
        openvdb::FloatGrid::ConstAccessor acc = grid->getConstAccessor();
#pragma omp for schedule(static)
        for (int k = 0; k < dims[2]; ++k)
            for (int j = 0; j < dims[1]; ++j)
                for (int i = 0; i < dims[0]; ++i) {
                    const int e[3] = {i, j, k};
                    openvdb::Coord c;
                    for (int a = 0; a < 3; ++a) {
                        const int s = L.src_axis[a];
                        c[s] = L.flip[a] ? hi[s] - e[a] : lo[s] + e[a];
                    }
                    dense[std::size_t(i) + std::size_t(dims[0]) * (std::size_t(j) + std::size_t(dims[1]) * k)] =
                        acc.getValue(c) * gain;
                }
    }
    // Values in [0, 1], named by the file's own voxel index.
    for (std::size_t n = 0; n < dense.size(); ++n) {
        const float v = dense[n];
        if (v >= 0.0f && v <= 1.0f) continue;
        const int i = int(n % std::size_t(dims[0])), j = int(n / std::size_t(dims[0]) % std::size_t(dims[1])),
                  k = int(n / (std::size_t(dims[0]) * std::size_t(dims[1])));
        const int e[3] = {i, j, k};
        int c[3];
        for (int a = 0; a < 3; ++a) {
            const int s = L.src_axis[a];
            c[s] = L.flip[a] ? hi[s] - e[a] : lo[s] + e[a];
        }
        throw core::Error(
            where + ": voxel (" + std::to_string(c[0]) + "," + std::to_string(c[1]) + "," + std::to_string(c[2]) + ")",
            "density " + core::format_number(v, 6) + (options.density_scale != 1.0 ? " (after density_scale)" : "") +
                " is outside [0, 1]; scale the grid with \"density_scale\"");
    }
    f.file.close();

    // Separable box filter onto the density grid (axes whose voxels already match are copies).
    const core::GridGeometry& g = info.density;
    const int out[3] = {g.dims.x, g.dims.y, g.dims.z};
    for (int a = 0; a < 3; ++a) {
        const double r = g.voxel_size / info.source_voxel[a];
        if (r == 1.0 && out[a] == dims[a]) continue;
        dense = resample_axis(dense, dims, a, out[a], r);
    }
    core::Grid3<float> result;
    result.geom = g;
    result.data = std::move(dense);
    return result;
}

void save_vdb(const std::filesystem::path& path, std::span<const VdbOutputGrid> grids,
              const std::vector<std::pair<std::string, std::string>>& file_text) {
    initialize_openvdb();
    openvdb::GridCPtrVec out;
    for (const VdbOutputGrid& og : grids) {
        FULGUR_ASSERT(og.values && og.values->data.size() == og.values->geom.cell_count(),
                      "save_vdb: a grid without values or whose data size does not match its dimensions");
        const core::Grid3<float>& v = *og.values;
        core::validate_geometry(v.geom, path.string() + ": grid " + in_quotes(og.name));
        core::check_finite(v, path.string() + ": grid " + in_quotes(og.name));
        openvdb::FloatGrid::Ptr g = openvdb::FloatGrid::create(0.0f);
        g->setName(og.name);
        g->setGridClass(og.fog_volume ? openvdb::GRID_FOG_VOLUME : openvdb::GRID_UNKNOWN);
        // Index (i,j,k) -> world: its centre, origin + (ijk + 1/2) h, in metres.
        openvdb::math::Transform::Ptr xf = openvdb::math::Transform::createLinearTransform(v.geom.voxel_size);
        xf->postTranslate(openvdb::Vec3d(v.geom.origin.x, v.geom.origin.y, v.geom.origin.z) +
                          openvdb::Vec3d(0.5 * v.geom.voxel_size));
        g->setTransform(xf);
        {
            openvdb::FloatGrid::Accessor acc = g->getAccessor();
            const core::Int3 d = v.dims();
            for (int k = 0; k < d.z; ++k)
                for (int j = 0; j < d.y; ++j)
                    for (int i = 0; i < d.x; ++i) acc.setValueOn(openvdb::Coord(i, j, k), v.at(i, j, k));
        }
        openvdb::tools::prune(g->tree());  // constant blocks (empty space) become active tiles
        for (const auto& [k, s] : og.text) g->insertMeta(k, openvdb::StringMetadata(s));
        for (const auto& [k, x] : og.vectors) g->insertMeta(k, openvdb::Vec3DMetadata(openvdb::Vec3d(x.x, x.y, x.z)));
        for (const auto& [k, x] : og.numbers) g->insertMeta(k, openvdb::DoubleMetadata(x));
        out.push_back(g);
    }
    openvdb::MetaMap meta;
    for (const auto& [k, s] : file_text) meta.insertMeta(k, openvdb::StringMetadata(s));
    std::ostringstream bytes(std::ios_base::out | std::ios_base::binary);
    guarded(path, "could not be encoded", [&] { SeekableArchive().write_to(bytes, out, meta); });
    core::AtomicFile file(path);
    file.write(bytes.view());
    file.commit();
}

}  // namespace fulgur::cloud
