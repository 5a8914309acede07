// OpenVDB import (a float grid -> the engine's density grid, box-filtered) and export (dense
// grids -> a .vdb with their world transforms and metadata). cloud.h names no OpenVDB type.
//
// Reading is contained. OpenVDB's reader trusts its input: a flipped bit in a tree's topology
// corrupts its heap (glibc aborts the process), a truncated file makes it allocate gigabytes,
// and no check after the read can help. So every read runs in a forked child process
// (detail/vdb_child.h) under a memory and a time limit, which sends what it read over a pipe
// in small fixed-layout records (detail/vdb_records.h): the grids' descriptors, then, for a
// load, the chosen grid's background, active box, leaves and non-background tiles. The parent
// (detail/vdb_parent.h) takes nothing on trust: it reads every record with bounded sizes,
// checks the descriptors itself (the same inspect() the child ran, detail/vdb_layout.h),
// fills only the cells of the box it allocated (here), checks every value, and turns a crash,
// a kill, an overrun or a malformed record into core::Error naming the file. Writing
// (save_vdb: trusted data) stays in the process; it is the only OpenVDB use here.
#include "cloud/cloud.h"

#include "cloud/detail/vdb_child.h"
#include "cloud/detail/vdb_layout.h"
#include "cloud/detail/vdb_parent.h"
#include "cloud/detail/vdb_records.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

namespace fulgur::cloud {

using namespace detail::vdb;

namespace {

// Runs `f`, turning OpenVDB's exceptions (a failed write) into core::Error naming the file;
// `what` says what failed.
template <class F>
auto guarded(const std::filesystem::path& path, const char* what, F&& f) {
    try {
        return f();
    } catch (const openvdb::Exception& e) {
        throw core::Error(path.string(), std::string(what) + " (OpenVDB: " + e.what() + ")");
    }
}

// io::Archive's seekable write into any stream (io::File writes it only to a path, io::Stream
// only without grid offsets): a file with offsets lets readers take its descriptors and
// statistics without reading the voxels, as inspect_vdb does.
class SeekableArchive : public openvdb::io::Archive {
public:
    void write_to(std::ostream& os, const openvdb::GridCPtrVec& grids, const openvdb::MetaMap& meta) const {
        openvdb::io::Archive::write(os, grids, /*seekable=*/true, meta);
    }
};

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

// The grid's background and active box, checked: the statistics sized the load, so a tree
// reaching beyond them is refused, not allocated.
void receive_background_and_box(Reader& reader, const Layout& L, const std::string& where) {
    reader.expect(kBackground, "the background");
    const auto background = reader.get<float>();
    if (background != 0.0f)
        throw core::Error(where, "has background " + core::format_number(background, 6) +
                                     "; a density grid's background (its value outside the active voxels) must be 0");
    reader.expect(kActiveBox, "the active box");
    const bool empty = reader.get<std::uint8_t>() != 0;
    const auto box = reader.get<std::array<std::int32_t, 6>>();
    const Box actual{{box[0], box[1], box[2]}, {box[3], box[4], box[5]}};
    if (!empty && !actual.empty() && !L.bbox.contains(actual)) {
        std::ostringstream m;
        m << "its active voxels span " << actual.text() << ", beyond the box its metadata states (" << L.bbox.text()
          << "); refusing to load a file whose size was misstated";
        throw core::Error(where, m.str());
    }
}

// The file's box as a dense array in the engine's axis order, from the child's leaves and
// tiles (the background, 0, everywhere else), times `gain`. Only cells inside the box are
// written, whatever the records say.
std::vector<float> receive_voxels(Reader& reader, const Layout& L, float gain) {
    const int dims[3] = {L.info.source_dims.x, L.info.source_dims.y, L.info.source_dims.z};
    std::vector<float> dense(std::size_t{1} * std::size_t(dims[0]) * std::size_t(dims[1]) * std::size_t(dims[2]));
    const std::array<std::int32_t, 3>& lo = L.bbox.min;
    const std::array<std::int32_t, 3>& hi = L.bbox.max;
    // The engine's cell of file voxel c (inside the box).
    auto cell = [&](const std::int64_t c[3]) {
        std::size_t e[3];
        for (int a = 0; a < 3; ++a) {
            const int s = L.src_axis[a];
            e[a] = std::size_t(L.flip[a] ? hi[s] - c[s] : c[s] - lo[s]);
        }
        return e[0] + std::size_t(dims[0]) * (e[1] + std::size_t(dims[1]) * e[2]);
    };
    std::array<float, kLeafValues> leaf;
    for (;;) {
        const std::uint8_t tag = reader.get_tag();
        if (tag == kDone) break;
        if (tag == kLeaf) {
            const auto o = reader.get<std::array<std::int32_t, 3>>();
            reader.get_bytes(leaf.data(), sizeof leaf);
            std::int64_t c[3];
            for (int x = 0; x < kLeafEdge; ++x)
                for (int y = 0; y < kLeafEdge; ++y)
                    for (int z = 0; z < kLeafEdge; ++z) {
                        c[0] = std::int64_t(o[0]) + x;
                        c[1] = std::int64_t(o[1]) + y;
                        c[2] = std::int64_t(o[2]) + z;
                        if (c[0] < lo[0] || c[0] > hi[0] || c[1] < lo[1] || c[1] > hi[1] || c[2] < lo[2] ||
                            c[2] > hi[2])
                            continue;
                        dense[cell(c)] = leaf[std::size_t(x << 6 | y << 3 | z)] * gain;
                    }
        } else if (tag == kTile) {
            const auto t = reader.get<std::array<std::int32_t, 4>>();
            const float v = reader.get<float>() * gain;
            if (t[3] != kLeafEdge && t[3] != kLowerEdge && t[3] != kUpperEdge)
                reader.malformed("a tile of " + std::to_string(t[3]) + " voxels");
            std::int64_t from[3], to[3];
            bool inside = true;
            for (int a = 0; a < 3; ++a) {
                from[a] = std::max<std::int64_t>(t[a], lo[a]);
                to[a] = std::min<std::int64_t>(std::int64_t(t[a]) + t[3] - 1, hi[a]);
                inside = inside && from[a] <= to[a];
            }
            if (!inside) continue;
            std::int64_t c[3];
            for (c[2] = from[2]; c[2] <= to[2]; ++c[2])
                for (c[1] = from[1]; c[1] <= to[1]; ++c[1])
                    for (c[0] = from[0]; c[0] <= to[0]; ++c[0]) dense[cell(c)] = v;
        } else {
            reader.malformed("record " + std::to_string(int(tag)) + " among the voxels");
        }
    }
    return dense;
}

// Values in [0, 1], named by the file's own voxel index.
void check_values(const std::vector<float>& dense, const Layout& L, const std::string& where,
                  const VdbImport& options) {
    const int dims[3] = {L.info.source_dims.x, L.info.source_dims.y, L.info.source_dims.z};
    const std::array<std::int32_t, 3>& lo = L.bbox.min;
    const std::array<std::int32_t, 3>& hi = L.bbox.max;
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
            "density " + core::format_number(v, 9) + (options.density_scale != 1.0 ? " (after density_scale)" : "") +
                " is outside [0, 1]; scale the grid with \"density_scale\"");
    }
}

}  // namespace

VdbInfo inspect_vdb(const std::filesystem::path& path, const VdbImport& options) {
    check_options(options);
    const std::uint64_t size = core::check_readable_file(path, kMaxVdbFileBytes, "OpenVDB");
    Reader reader(path, size, options.max_bytes, [&](Out& out) { child_inspect(path, out); });
    const std::vector<GridFacts> facts = receive_facts(reader);
    reader.expect(kDone, "the end");
    reader.finish();
    return inspect(facts, path, options).info;
}

core::Grid3<float> load_vdb(const std::filesystem::path& path, const VdbImport& options) {
    check_options(options);
    const std::uint64_t size = core::check_readable_file(path, kMaxVdbFileBytes, "OpenVDB");
    Reader reader(path, size, options.max_bytes, [&](Out& out) { child_load(path, options, out); });
    const Layout L = inspect(receive_facts(reader), path, options);
    const VdbInfo& info = L.info;
    const std::string where = path.string() + ": grid " + in_quotes(info.grid);
    reader.set_where(where);
    if (info.load_bytes > options.max_bytes)
        throw core::Error(where, "loading it would need about " + core::format_bytes(double(info.load_bytes)) + " (" +
                                     dims_text(info.source_dims) + " file voxels onto " + dims_text(info.density.dims) +
                                     "), over the limit of " + core::format_bytes(double(options.max_bytes)));
    reader.set_budget(options.max_bytes - (info.load_bytes - L.tree_bytes));
    reader.allow_dense(info.load_bytes);

    receive_background_and_box(reader, L, where);
    std::vector<float> dense = receive_voxels(reader, L, float(options.density_scale));
    reader.finish();
    check_values(dense, L, where, options);

    // Separable box filter onto the density grid (axes whose voxels already match are copies).
    int dims[3] = {info.source_dims.x, info.source_dims.y, info.source_dims.z};
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
