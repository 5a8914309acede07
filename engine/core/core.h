// fulgur::core — the foundation every module builds on.
//
//  * Error / FULGUR_ASSERT: the two tiers of failure. `Error` is thrown for bad *data*
//    (files, scene fields, command-line values); its message names where (file, field,
//    byte offset) and what was expected. FULGUR_ASSERT aborts on *programmer misuse*
//    (violated preconditions) and is active in every build type.
//  * Grid3<T>: a dense 3D voxel grid with physical geometry (voxel size in metres,
//    origin of the grid's lower corner) and cell-centred trilinear sampling.
//  * Rng: PCG32 (O'Neill 2014), deterministic per (seed, stream).
//  * Threads: OpenMP underneath; thread_count()/set_thread_count() and parallel_for.
//  * NRRD (header + raw float32) import/export; PNG export (stb_image_write).
#pragma once

#include <glm/vec3.hpp>

#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fulgur::core {

// ---------------------------------------------------------------------------------------
// Errors

/// Bad input (data, files, parameters). `where` names the file, field or byte offset;
/// `what` says what was wrong and what was expected. what() returns "where: what".
class Error : public std::runtime_error {
public:
    Error(std::string where, std::string what);
    const std::string& where() const noexcept { return where_; }
    const std::string& reason() const noexcept { return reason_; }

private:
    std::string where_;
    std::string reason_;
};

/// Aborts with file:line and the message. For programmer misuse only, never for data.
[[noreturn]] void assertion_failed(const char* expr, const char* file, int line, const char* msg);

#define FULGUR_ASSERT(cond, msg)                                                       \
    do {                                                                               \
        if (!(cond)) ::fulgur::core::assertion_failed(#cond, __FILE__, __LINE__, msg); \
    } while (0)

// ---------------------------------------------------------------------------------------
// Grids

struct Int3 {
    int x = 0, y = 0, z = 0;
    constexpr std::size_t volume() const noexcept { return std::size_t(x) * std::size_t(y) * std::size_t(z); }
    constexpr bool operator==(const Int3&) const = default;
};

/// Physical placement of a voxel grid. Voxel (i,j,k) covers
/// [origin + (i,j,k)*voxel_size, origin + (i+1,j+1,k+1)*voxel_size); its sample sits at the
/// centre. z is up. Units: metres.
struct GridGeometry {
    Int3 dims;
    double voxel_size = 1.0;
    glm::dvec3 origin{0.0};

    std::size_t cell_count() const noexcept { return dims.volume(); }
    std::size_t index(int i, int j, int k) const noexcept {
        return std::size_t(i) + std::size_t(dims.x) * (std::size_t(j) + std::size_t(dims.y) * std::size_t(k));
    }
    Int3 unindex(std::size_t idx) const noexcept;
    glm::dvec3 centre(int i, int j, int k) const noexcept { return origin + (glm::dvec3(i, j, k) + 0.5) * voxel_size; }
    glm::dvec3 extent() const noexcept { return glm::dvec3(dims.x, dims.y, dims.z) * voxel_size; }
    glm::dvec3 upper() const noexcept { return origin + extent(); }
    /// Continuous voxel coordinates: the centre of voxel i maps to i + 0.5.
    glm::dvec3 to_voxel(const glm::dvec3& world) const noexcept { return (world - origin) / voxel_size; }
    bool contains(const glm::dvec3& world) const noexcept;
    bool operator==(const GridGeometry&) const = default;
};

/// Dense 3D grid, x fastest. Values are samples at voxel centres.
template <class T>
struct Grid3 {
    GridGeometry geom;
    std::vector<T> data;

    Grid3() = default;
    explicit Grid3(const GridGeometry& g, T fill = T{}) : geom(g), data(g.cell_count(), fill) {}

    const Int3& dims() const noexcept { return geom.dims; }
    std::size_t size() const noexcept { return data.size(); }
    T& at(int i, int j, int k) noexcept { return data[geom.index(i, j, k)]; }
    const T& at(int i, int j, int k) const noexcept { return data[geom.index(i, j, k)]; }

    /// Trilinear interpolation between voxel centres at a world position, clamped to the
    /// outermost centres (constant extrapolation outside the grid).
    T sample(const glm::dvec3& world) const noexcept;
};

/// Clips the parameter interval [t0, t1] of the ray o + t d (d need not be unit) against the
/// closed box [lo, hi] by slabs. Returns false (t0, t1 then unspecified) when the clipped
/// interval is empty or a coordinate is NaN; an axis-parallel ray (a component of d exactly 0)
/// is handled without 0 * inf. Used by the voxel traversal, Monte Carlo and the renderer.
inline bool clip_ray_to_box(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi,
                            double& t0, double& t1) noexcept {
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0) {
            if (!(o[a] >= lo[a] && o[a] <= hi[a])) return false;  // also rejects NaN
            continue;
        }
        const double inv = 1.0 / d[a];
        double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
        if (ta > tb) std::swap(ta, tb);
        if (ta > t0) t0 = ta;
        if (tb < t1) t1 = tb;
    }
    return t0 < t1;  // false for NaN too
}

/// Voxel sizes a grid may have, in metres: below a micrometre a voxel's volume and 1/r^2 near
/// a source leave double precision's comfortable range; above 1000 km no cloud is meant.
inline constexpr double kMinVoxelSize = 1e-6, kMaxVoxelSize = 1e6;
/// Largest |origin| coordinate of a grid, in metres.
inline constexpr double kMaxOrigin = 1e9;

/// Validates a geometry (dims in [1, 4096], voxel size in [kMinVoxelSize, kMaxVoxelSize],
/// |origin| <= kMaxOrigin); throws Error naming `where`.
void validate_geometry(const GridGeometry& g, std::string_view where);

/// Box-filter downsample by an integer factor per axis (dims must divide exactly, or the
/// trailing partial block averages only the voxels it has). Voxel size grows by `factor`.
Grid3<float> downsample(const Grid3<float>& src, int factor);

// ---------------------------------------------------------------------------------------
// Random numbers

/// PCG32 (XSH-RR, 64-bit state). Deterministic for a given (seed, stream); different
/// streams are independent sequences, so per-path or per-batch streams give results that
/// do not depend on the thread count.
class Rng {
public:
    explicit Rng(std::uint64_t seed = 0x853c49e6748fea9bULL, std::uint64_t stream = 0xda3e39cb94b95bdbULL) noexcept;
    std::uint32_t next_u32() noexcept;
    /// Uniform in [0, 1) with 24 random bits.
    float uniform_float() noexcept { return float(next_u32() >> 8) * 0x1p-24f; }
    /// Uniform in [0, 1) with 53 random bits.
    double uniform() noexcept;
    /// Uniform integer in [0, bound) without modulo bias.
    std::uint32_t uniform_below(std::uint32_t bound) noexcept;
    /// Standard normal (Box-Muller, both draws consumed).
    double normal() noexcept;

private:
    std::uint64_t state_ = 0;
    std::uint64_t inc_ = 0;
};

/// Mixes several 64-bit values into one seed (SplitMix64 finalizer chain).
std::uint64_t hash_seed(std::uint64_t a, std::uint64_t b = 0, std::uint64_t c = 0) noexcept;

// ---------------------------------------------------------------------------------------
// Numerics

/// Neumaier compensated summation; use where a long accumulation decides a result.
struct CompensatedSum {
    double sum = 0.0, comp = 0.0;
    void add(double v) noexcept {
        const double t = sum + v;
        comp += (std::fabs(sum) >= std::fabs(v)) ? (sum - t) + v : (v - t) + sum;
        sum = t;
    }
    double value() const noexcept { return sum + comp; }
};

/// Relative L2 difference ||x - ref||_2 / ||ref||_2 of paired values, accumulated pair by
/// pair in compensated double sums; ||x - ref||_2 when the reference is all zero.
class RelativeL2 {
public:
    void add(double x, double ref) noexcept {
        const double d = x - ref;
        diff_.add(d * d);
        ref_.add(ref * ref);
    }
    double value() const noexcept {
        const double r = ref_.value();
        return std::sqrt(diff_.value() / (r > 0.0 ? r : 1.0));
    }
    /// ||ref||_2 of the pairs added so far.
    double reference_norm() const noexcept { return std::sqrt(ref_.value()); }

private:
    CompensatedSum diff_, ref_;
};

/// RelativeL2 of two arrays of the same length (element i of x against element i of ref).
double relative_l2(std::span<const float> x, std::span<const float> ref) noexcept;
double relative_l2(std::span<const double> x, std::span<const double> ref) noexcept;

// ---------------------------------------------------------------------------------------
// Threads and time

/// Threads used by parallel regions (default: all hardware threads).
int thread_count() noexcept;
/// Sets the thread count for subsequent parallel regions (n >= 1).
void set_thread_count(int n);

/// For its lifetime, parallel regions started from the calling thread use n threads (n >= 1)
/// whatever set_thread_count says: a worker thread keeps its solves to its own share of the
/// cores. Nests (the innermost wins) and restores the previous value.
class ScopedThreadCount {
public:
    explicit ScopedThreadCount(int n);
    ~ScopedThreadCount();
    ScopedThreadCount(const ScopedThreadCount&) = delete;
    ScopedThreadCount& operator=(const ScopedThreadCount&) = delete;

private:
    int previous_;
};

/// One background thread that runs submitted jobs one at a time, in the order submitted,
/// each with its parallel regions kept to `threads` threads (ScopedThreadCount): the run
/// time's solves ahead of the frame (strikes, the sun) share the cores with the frame loop
/// this way. A job handles its own errors (an exception escaping a job is a programmer error
/// and terminates). Destruction lets the running job finish, drops queued ones and joins.
class Worker {
public:
    explicit Worker(int threads);
    ~Worker();
    Worker(const Worker&) = delete;
    Worker& operator=(const Worker&) = delete;

    /// Queues `job`. With `latest_only`, jobs queued and not yet started are dropped first:
    /// only the newest request matters (a sun that moved again before its solve began).
    void submit(std::function<void()> job, bool latest_only = false);
    /// While paused, no queued job starts; the running one finishes.
    void set_paused(bool paused);
    /// True while a job runs or is queued.
    bool busy() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Calls fn(i) for i in [begin, end) over thread_count() threads with a static schedule.
template <class F>
void parallel_for(std::int64_t begin, std::int64_t end, F&& fn) {
#pragma omp parallel for schedule(static) num_threads(thread_count())
    for (std::int64_t i = begin; i < end; ++i) fn(i);
}

/// Like parallel_for but with dynamic scheduling in chunks, for uneven work items.
template <class F>
void parallel_for_dynamic(std::int64_t begin, std::int64_t end, F&& fn, int chunk = 1) {
#pragma omp parallel for schedule(dynamic, chunk) num_threads(thread_count())
    for (std::int64_t i = begin; i < end; ++i) fn(i);
}

/// A duration for people: "12.3 s", "4.5 min", "1.2 h" ("?" when negative or not finite).
std::string format_seconds(double seconds);
/// A size for people (powers of ten): "512 B", "12.3 kB", "229.4 MB", "1.19 GB".
std::string format_bytes(double bytes);
/// A number with `significant_digits` significant digits, printf's "%.*g" in the C locale
/// ("0.1", "1e+30", "inf"): 6 for messages, 17 to round-trip any double.
std::string format_number(double v, int significant_digits = 6);

class Stopwatch {
public:
    Stopwatch() noexcept : start_(std::chrono::steady_clock::now()) {}
    void reset() noexcept { start_ = std::chrono::steady_clock::now(); }
    double seconds() const noexcept {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }
    double milliseconds() const noexcept { return seconds() * 1e3; }

private:
    std::chrono::steady_clock::time_point start_;
};

// ---------------------------------------------------------------------------------------
// Files: bounded reads, safe writes (files.cpp)
//
// Every file the engine reads is checked first: a regular file (a FIFO would block, /dev/zero
// never ends, a directory is no file) no larger than a limit the format states. Every file it
// writes goes through AtomicFile: never half-written, never through a device, never mixed by
// two writers, and its temporary never left behind by an exception or a signal.

/// Throws Error naming `path` unless it is a regular file of at most `max_bytes`; returns its
/// size. `what` names the kind of file in messages ("scene", "NRRD", ".fgb").
std::uint64_t check_readable_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what);

/// The whole file after check_readable_file (also fails if the file changes while read).
std::string read_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what);

/// Throws Error(where, "<what> <i> is NaN|infinite; refusing to write ...") at the first
/// non-finite value: called before any value reaches a file or an image.
void check_finite(std::span<const float> values, std::string_view where, std::string_view what = "value");
/// The same for a grid; the message names the voxel (i,j,k).
void check_finite(const Grid3<float>& grid, std::string_view where);

/// A file a tool reads or writes, with its role in messages ("scene", "output", "report").
struct NamedPath {
    std::string role;
    std::filesystem::path path;
};
/// Throws Error naming the output when an output is one of the inputs or another output (the
/// same path after resolving ".", ".." and symbolic links, or the same file through a hard
/// link), or exists and is not a regular file (a directory, /dev/full): called by the tools
/// before any work, so a bad output costs no bake.
void check_distinct_files(std::span<const NamedPath> inputs, std::span<const NamedPath> outputs);

/// An exclusive advisory lock (flock) on "<target>.lock" for writers of `target` in different
/// processes; waits for the current holder. The lock file is removed on release (and on the
/// signals AtomicFile handles). Nested locks on one target in one process are allowed (the
/// inner one is a no-op): it serializes processes, not the threads of one process.
class FileLock {
public:
    explicit FileLock(const std::filesystem::path& target);
    ~FileLock();
    FileLock(const FileLock&) = delete;
    FileLock& operator=(const FileLock&) = delete;

private:
    std::filesystem::path lock_path_;
};

/// Writes `target` safely: holds its FileLock, writes "<target>.<pid>.tmp" in the same
/// directory, and commit() flushes, syncs, closes (each checked: a full disk or a file-size
/// limit is an Error, not a short file) and renames the temporary over the target atomically.
/// Destroyed without commit() (an exception), or on SIGINT, SIGTERM or SIGHUP, the temporary
/// is removed; temporaries a killed process left for the same target are removed on open. A
/// target that exists but is not a regular file (a directory, a device such as /dev/full) is
/// refused; a symbolic link is followed. Errors name the target.
class AtomicFile {
public:
    explicit AtomicFile(std::filesystem::path target);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    void write(const void* data, std::size_t n);
    void write(std::string_view bytes) { write(bytes.data(), bytes.size()); }
    /// Moves the write position (for formats whose header is written last).
    void seek(std::uint64_t offset);
    /// The temporary's stream, for writers that need one (stb_image_write, fseek); check
    /// their results and call fail() on error.
    std::FILE* stream();
    [[noreturn]] void fail(const std::string& what);
    void commit();

    const std::filesystem::path& target() const noexcept { return target_; }
    const std::filesystem::path& temp_path() const noexcept { return temp_; }

private:
    void discard() noexcept;
    std::filesystem::path target_, temp_;
    std::unique_ptr<FileLock> lock_;
    std::FILE* file_ = nullptr;
    int slot_ = -1;
    bool committed_ = false;
};

/// `bytes` into `path` through AtomicFile (reports, CSV, SVG).
void write_file(const std::filesystem::path& path, std::string_view bytes);

/// Writes a float32 grid as NRRD (attached header, raw little-endian data) with space
/// origin and spacing in metres, so ParaView / 3D Slicer place it correctly. Refuses a
/// non-finite value (check_finite) before writing; writes through AtomicFile.
void write_nrrd(const std::filesystem::path& path, const Grid3<float>& grid, std::string_view content = {});

/// The geometry and data layout of a NRRD, from its header alone (nothing is allocated from
/// the file's numbers): sizes, spacing in [kMinVoxelSize, kMaxVoxelSize], origin, and a file
/// size that matches the float32 data exactly. For sizing a load before doing it.
struct NrrdHeader {
    GridGeometry geom;
    std::uint64_t data_offset = 0;
    std::uint64_t file_size = 0;
};
/// Largest NRRD read by default (4 GiB: a 1024^3 float32 grid plus its header).
inline constexpr std::uint64_t kMaxNrrdBytes = (std::uint64_t(1) << 32) + (1 << 16);
NrrdHeader read_nrrd_header(const std::filesystem::path& path, std::uint64_t max_bytes = kMaxNrrdBytes);

/// Reads a NRRD written by write_nrrd or any 3D float32 raw/attached NRRD of at most
/// `max_bytes` (a regular file: check_readable_file). Validates the header and the data
/// size before allocating; every error names the file and the field or byte offset.
Grid3<float> read_nrrd(const std::filesystem::path& path, std::uint64_t max_bytes = kMaxNrrdBytes);

/// Writes an 8-bit RGB or RGBA PNG (channels 3 or 4), rows top to bottom.
void write_png(const std::filesystem::path& path, int width, int height, int channels,
               std::span<const std::uint8_t> pixels);

/// Maps a scalar in [0,1] to a perceptual pseudo-colour (viridis-like), 8-bit RGB.
void pseudo_colour(double t, std::uint8_t rgb[3]) noexcept;

// ---------------------------------------------------------------------------------------
// Template definitions

template <class T>
T Grid3<T>::sample(const glm::dvec3& world) const noexcept {
    const glm::dvec3 u = geom.to_voxel(world) - 0.5;
    const int nx = geom.dims.x, ny = geom.dims.y, nz = geom.dims.z;
    auto split = [](double v, int n, int& i0, int& i1, double& f) {
        if (!(v > 0.0)) {
            i0 = i1 = 0;
            f = 0.0;
            return;
        }  // also catches NaN
        if (v >= double(n - 1)) {
            i0 = i1 = n - 1;
            f = 0.0;
            return;
        }
        i0 = int(v);
        i1 = i0 + 1;
        f = v - double(i0);
    };
    int x0, x1, y0, y1, z0, z1;
    double fx, fy, fz;
    split(u.x, nx, x0, x1, fx);
    split(u.y, ny, y0, y1, fy);
    split(u.z, nz, z0, z1, fz);
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    const double c00 = lerp(double(at(x0, y0, z0)), double(at(x1, y0, z0)), fx);
    const double c10 = lerp(double(at(x0, y1, z0)), double(at(x1, y1, z0)), fx);
    const double c01 = lerp(double(at(x0, y0, z1)), double(at(x1, y0, z1)), fx);
    const double c11 = lerp(double(at(x0, y1, z1)), double(at(x1, y1, z1)), fx);
    return T(lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz));
}

}  // namespace fulgur::core
