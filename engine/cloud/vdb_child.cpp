// The reading child of a contained OpenVDB read (detail/vdb_child.h): the only place that runs
// OpenVDB's reader. OpenVDB trusts its input (a flipped bit in a tree's topology corrupts its
// heap, a truncated file makes it allocate gigabytes), so it runs here, in a process forked
// for one read, under a memory limit (RLIMIT_AS: the load's budget plus a margin for the
// library), a CPU time limit and no core file, with only its pipe to the parent open. It
// sends what it read as the fixed-layout records of detail/vdb_records.h: the grids'
// descriptors, then, for a load, the chosen grid's background, active box, leaves and
// non-background tiles. The parent checks all of it.
#include "cloud/detail/vdb_child.h"

#include "cloud/detail/vdb_layout.h"
#include "cloud/detail/vdb_records.h"

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

#if FULGUR_VDB_SANITIZED
#include <sanitizer/common_interface_defs.h>
#endif

namespace fulgur::cloud::detail::vdb {

// The child's records, buffered; a failed write (the parent gone or done) ends the child.
class Out {
public:
    explicit Out(int fd) : fd_(fd) {}
    template <class T>
    void put(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>);
        buf_.append(reinterpret_cast<const char*>(&v), sizeof v);
        if (buf_.size() >= (1u << 20)) flush();
    }
    void put_bytes(const void* p, std::size_t n) {
        buf_.append(static_cast<const char*>(p), n);
        if (buf_.size() >= (1u << 20)) flush();
    }
    void put_string(std::string_view s) {
        put(std::uint32_t(s.size()));
        put_bytes(s.data(), s.size());
    }
    // A refusal about the file, the chosen grid (about 1) or a grid it names (about 2).
    void error(std::uint8_t about, std::string_view reason, std::string_view grid = {}) {
        put(kError);
        put(about);
        put_string(grid.substr(0, kMaxNameBytes));
        put_string(reason.substr(0, kMaxReasonBytes));
    }
    void flush() {
        std::size_t done = 0;
        while (done < buf_.size()) {
            const ssize_t n = ::write(fd_, buf_.data() + done, buf_.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) ::_exit(kExitWriteFailed);
            done += std::size_t(n);
        }
        buf_.clear();
    }

private:
    int fd_;
    std::string buf_;
};

namespace {

using RootT = openvdb::FloatTree::RootNodeType;
using Upper = RootT::ChildNodeType;
using Lower = Upper::ChildNodeType;
using LeafT = Lower::ChildNodeType;

// The records' node sizes are the float tree's.
static_assert(int(LeafT::DIM) == kLeafEdge && int(LeafT::SIZE) == kLeafValues);
static_assert(int(Lower::DIM) == kLowerEdge && int(Upper::DIM) == kUpperEdge);

// The child's address space when it started (the parent's mappings, inherited): its memory
// limit counts from there.
std::uint64_t g_child_start_vm = 0;

// Limits the child's address space to its start plus `budget` plus the library's margin: the
// hard limit once (the whole budget), the soft limit per phase (the descriptors', then the
// tree's share), never above the hard one. Not in sanitized builds (see FULGUR_VDB_SANITIZED).
void limit_child_memory(std::uint64_t budget, bool hard = false) {
#if !FULGUR_VDB_SANITIZED
    if (g_child_start_vm == 0) return;  // /proc unreadable: the parent's watch still holds
    rlimit r{};
    if (::getrlimit(RLIMIT_AS, &r) != 0) return;
    const rlim_t want = rlim_t(add_saturated(g_child_start_vm, add_saturated(budget, kLibraryBytes)));
    if (hard) {
        if (r.rlim_max != RLIM_INFINITY && r.rlim_max < want) return;  // a tighter limit is already set
        r.rlim_max = want;
    }
    r.rlim_cur = std::min(want, r.rlim_max);
    ::setrlimit(RLIMIT_AS, &r);
#else
    (void)budget;
    (void)hard;
#endif
}

// The open file's grid descriptors (metadata and transforms, no voxels).
struct OpenFile {
    openvdb::io::File file;
    openvdb::GridPtrVecPtr grids;
    explicit OpenFile(const std::filesystem::path& path) : file(path.string()) {
        file.open(/*delayLoad=*/false);  // no memory-mapped leaves: every voxel is read once, here
        try {
            grids = file.readAllGridMetadata();
        } catch (const openvdb::ArithmeticError& e) {
            // OpenVDB inverts some maps as it reads them: a NaN, infinite or zero element
            // throws. Read the grids one by one to name the one it failed on.
            for (auto n = file.beginName(); n != file.endName(); ++n) try {
                    (void)file.readGridMetadata(n.gridName());
                } catch (const openvdb::ArithmeticError&) {
                    throw BadTransform{n.gridName(), cut(e.what())};
                }
            throw;
        }
    }
    // A grid whose transform OpenVDB could not build.
    struct BadTransform {
        std::string grid, what;
    };
};

// A grid's descriptor (metadata and transform); false (after an error record) when a name
// does not fit the records' bounds.
bool read_facts(const openvdb::GridBase& g, Out& out, GridFacts& F) {
    F.name = g.getName();
    F.value_type = g.valueType();
    const openvdb::math::Transform& xf = g.transform();
    F.map_type = xf.mapType();
    for (const std::string* s : {&F.name, &F.value_type, &F.map_type})
        if (s->size() > kMaxNameBytes) {
            out.error(0, "holds a grid or type name of " + std::to_string(s->size()) + " bytes (\"" + cut(*s, 40) +
                             "\"); at most " + std::to_string(kMaxNameBytes) + " are read");
            return false;
        }
    F.float_grid = g.isType<openvdb::FloatGrid>();
    if (const auto v = g.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MIN)) {
        F.has_bbox_min = true;
        for (int a = 0; a < 3; ++a) F.bbox_min[a] = v->value()[a];
    }
    if (const auto v = g.getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MAX)) {
        F.has_bbox_max = true;
        for (int a = 0; a < 3; ++a) F.bbox_max[a] = v->value()[a];
    }
    if (const auto v = g.getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_VOXEL_COUNT)) {
        F.has_count = true;
        F.count = v->value();
    }
    if (const auto v = g.getMetadata<openvdb::Int64Metadata>(openvdb::GridBase::META_FILE_MEM_BYTES)) {
        F.has_mem = true;
        F.mem = v->value();
    }
    F.linear = xf.isLinear();
    if (F.linear) {
        // Forward applications only (see check_transform in vdb_layout.cpp).
        const openvdb::math::MapBase::ConstPtr map = xf.baseMap();
        for (int r = 0; r < 3; ++r) {
            openvdb::Vec3d e(0.0);
            e[r] = 1.0;
            const openvdb::Vec3d row = map->applyJacobian(e);
            for (int c = 0; c < 3; ++c) F.m[r][c] = row[c];
        }
        const openvdb::Vec3d t = map->applyMap(openvdb::Vec3d(0.0));
        for (int c = 0; c < 3; ++c) F.m[3][c] = t[c];
    }
    return true;
}

// Reads the descriptors and sends them; false (after an error record) when they do not fit
// the records' bounds.
bool send_facts(const OpenFile& f, Out& out, std::vector<GridFacts>& facts) {
    if (f.grids->size() > kMaxGrids) {
        out.error(0, "holds " + std::to_string(f.grids->size()) + " grids; at most " + std::to_string(kMaxGrids) +
                         " are read");
        return false;
    }
    for (const openvdb::GridBase::Ptr& g : *f.grids) {
        GridFacts F;
        if (!read_facts(*g, out, F)) return false;
        facts.push_back(std::move(F));
    }
    out.put(kFacts);
    out.put(std::uint32_t(facts.size()));
    for (const GridFacts& F : facts) {
        out.put_string(F.name);
        out.put_string(F.value_type);
        out.put_string(F.map_type);
        out.put(std::uint8_t((F.float_grid ? 1 : 0) | (F.linear ? 2 : 0) | (F.has_bbox_min ? 4 : 0) |
                             (F.has_bbox_max ? 8 : 0) | (F.has_count ? 16 : 0) | (F.has_mem ? 32 : 0)));
        out.put(F.bbox_min);
        out.put(F.bbox_max);
        out.put(F.count);
        out.put(F.mem);
        out.put(F.m);
    }
    return true;
}

// Calls tile(origin, edge, value, active) for every tile of the tree (root, upper and lower
// nodes' values that are not children) and leaf(leaf) for every leaf: serially (no TBB in
// the child: its worker threads did not survive the fork).
template <class TileF, class LeafF>
void visit_tree(const openvdb::FloatTree& tree, TileF&& tile, LeafF&& leaf) {
    const RootT& root = tree.root();
    for (auto t = root.cbeginValueAll(); t; ++t) tile(t.getCoord(), Upper::DIM, *t, t.isValueOn());
    for (auto u = root.cbeginChildOn(); u; ++u) {
        for (auto t = u->cbeginValueAll(); t; ++t) tile(t.getCoord(), Lower::DIM, *t, t.isValueOn());
        for (auto l = u->cbeginChildOn(); l; ++l) {
            for (auto t = l->cbeginValueAll(); t; ++t) tile(t.getCoord(), LeafT::DIM, *t, t.isValueOn());
            for (auto v = l->cbeginChildOn(); v; ++v) leaf(*v);
        }
    }
}

openvdb::CoordBBox coord_box(const Box& b) {
    return openvdb::CoordBBox(openvdb::Coord(b.min[0], b.min[1], b.min[2]),
                              openvdb::Coord(b.max[0], b.max[1], b.max[2]));
}

// The grid's active box, for the parent's check against the statistics; false when it
// reaches beyond `bbox` (the parent refuses it).
bool send_active_box(const openvdb::FloatGrid& grid, const openvdb::CoordBBox& bbox, Out& out) {
    openvdb::CoordBBox active;
    visit_tree(
        grid.tree(),
        [&](const openvdb::Coord& o, int edge, float, bool on) {
            if (on) active.expand(openvdb::CoordBBox::createCube(o, edge));
        },
        [&](const LeafT& leaf) { leaf.evalActiveBoundingBox(active); });
    out.put(kActiveBox);
    out.put(std::uint8_t(active.empty()));
    const std::int32_t box[6] = {active.min().x(), active.min().y(), active.min().z(),
                                 active.max().x(), active.max().y(), active.max().z()};
    out.put(box);
    return active.empty() || bbox.isInside(active);
}

// The values over `bbox`: leaves whole (inactive voxels included, as an accessor reads them)
// and the tiles that differ from the background (0, which the parent's copy starts from);
// nothing outside the box.
void send_voxels(const openvdb::FloatGrid& grid, const openvdb::CoordBBox& bbox, float background, Out& out) {
    visit_tree(
        grid.tree(),
        [&](const openvdb::Coord& o, int edge, float v, bool) {
            if (std::memcmp(&v, &background, sizeof v) == 0) return;
            if (!bbox.hasOverlap(openvdb::CoordBBox::createCube(o, edge))) return;
            out.put(kTile);
            const std::int32_t head[4] = {o.x(), o.y(), o.z(), edge};
            out.put(head);
            out.put(v);
        },
        [&](const LeafT& leaf) {
            if (!bbox.hasOverlap(leaf.getNodeBoundingBox())) return;
            out.put(kLeaf);
            const std::int32_t head[3] = {leaf.origin().x(), leaf.origin().y(), leaf.origin().z()};
            out.put(head);
            out.put_bytes(leaf.buffer().data(), sizeof(float) * LeafT::SIZE);
        });
}

// Default dispositions for the signals, so a crash ends the child with its signal (not
// through a handler the parent installed: a fuzzer's crash report, AtomicFile's clean-up of
// the parent's temporaries), nothing blocked, no core file and a CPU limit of `seconds`.
void reset_signals_and_limits(double seconds) {
    for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE, SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP,
                          SIGSYS, SIGXCPU, SIGALRM, SIGVTALRM, SIGPROF})
        ::signal(sig, SIG_DFL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
#if FULGUR_VDB_SANITIZED
    __sanitizer_set_death_callback(nullptr);
#endif
    const rlimit no_core{0, 0};
    ::setrlimit(RLIMIT_CORE, &no_core);
    const rlim_t cpu = rlim_t(std::ceil(seconds)) + 1;
    const rlimit cpu_limit{cpu, cpu + 2};  // SIGXCPU, then SIGKILL
    ::setrlimit(RLIMIT_CPU, &cpu_limit);
}

// Only the pipe and /dev/null for the standard streams: what a corrupt file makes the library
// print belongs in the refusal, not on the terminal. Returns the pipe's new descriptor.
int keep_only_pipe(int fd) {
    const int out_fd = ::fcntl(fd, F_DUPFD, 3);
    const int null_fd = ::open("/dev/null", O_RDWR);
    if (out_fd < 0 || null_fd < 0) ::_exit(kExitWriteFailed);
    for (int s = 0; s < 3; ++s) ::dup2(null_fd, s);
#ifdef SYS_close_range
    if (out_fd > 3) ::syscall(SYS_close_range, 3u, unsigned(out_fd - 1), 0u);
    ::syscall(SYS_close_range, unsigned(out_fd + 1), ~0u, 0u);
#endif
    return out_fd;
}

}  // namespace

void initialize_openvdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

void child_inspect(const std::filesystem::path& path, Out& out) {
    const OpenFile f(path);
    std::vector<GridFacts> facts;
    if (send_facts(f, out, facts)) out.put(kDone);
}

void child_load(const std::filesystem::path& path, const VdbImport& options, Out& out) {
    OpenFile f(path);
    std::vector<GridFacts> facts;
    if (!send_facts(f, out, facts)) return;
    out.flush();
    Layout L;
    try {
        L = inspect(facts, path, options);
    } catch (const core::Error&) {
        return;  // the parent refuses it with the same message
    }
    if (L.info.load_bytes > options.max_bytes) return;
    // The tree gets what the budget leaves after the parent's dense copies.
    limit_child_memory(options.max_bytes - (L.info.load_bytes - L.tree_bytes));

    openvdb::FloatGrid::Ptr grid;
    try {
        grid = openvdb::gridPtrCast<openvdb::FloatGrid>(f.file.readGrid(L.info.grid));
    } catch (const openvdb::Exception& e) {
        out.error(1, "its grid could not be read (OpenVDB: " + cut(e.what()) + ")");
        return;
    }
    if (!grid) {
        out.error(1, "its grid could not be read as a float grid");
        return;
    }
    f.file.close();
    const float background = grid->background();
    out.put(kBackground);
    out.put(background);
    if (background != 0.0f) return;
    const openvdb::CoordBBox bbox = coord_box(L.bbox);
    if (!send_active_box(*grid, bbox, out)) return;
    send_voxels(*grid, bbox, background, out);
    out.put(kDone);
}

void child_main(int fd, pid_t parent, std::uint64_t budget, std::uint64_t first, double seconds,
                const ChildBody& body) {
    // Dies with the parent.
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(kExitWriteFailed);
    reset_signals_and_limits(seconds);
    const int out_fd = keep_only_pipe(fd);
    g_child_start_vm = statm_bytes(0, 0);
    limit_child_memory(budget, true);
    limit_child_memory(first);
    // After fork() only this thread exists: nothing parallel.
    const core::ScopedThreadCount one(1);
    Out out(out_fd);
    try {
        body(out);
    } catch (const std::bad_alloc&) {
        ::_exit(kExitOutOfMemory);
    } catch (const OpenFile::BadTransform& b) {
        out.error(2,
                  "has a transform OpenVDB cannot use (OpenVDB: " + b.what +
                      "): a NaN, infinite or zero element; refusing it",
                  b.grid);
    } catch (const openvdb::Exception& e) {
        out.error(0, "not a readable OpenVDB file (OpenVDB: " + cut(e.what()) + ")");
    } catch (const std::exception& e) {
        out.error(0, "not a readable OpenVDB file (" + cut(e.what()) + ")");
    } catch (...) {
        out.error(0, "not a readable OpenVDB file (an unknown exception)");
    }
    out.flush();
    ::_exit(0);
}

}  // namespace fulgur::cloud::detail::vdb
