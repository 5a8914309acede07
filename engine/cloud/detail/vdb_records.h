// Internal to fulgur::cloud: what both sides of a contained OpenVDB read share (see
// vdb_parent.h). The child (vdb_child.cpp) runs OpenVDB's reader and sends what it read over
// a pipe in small fixed-layout records; the parent (vdb_parent.cpp, vdb.cpp) reads them with
// bounded sizes and checks every value. Here: the records' tags and bounds, the grid
// descriptors they carry (GridFacts), the child's exit statuses and memory margin, and small
// helpers both sides use. No OpenVDB type: the parent's files do not include OpenVDB.
#pragma once

#include <sys/types.h>

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>

// Under AddressSanitizer (and the other sanitizers) the process reserves terabytes of shadow
// memory at start, so an address-space limit (RLIMIT_AS) would make every allocation of the
// child fail: sanitized builds skip it and rely on the parent's watch of the child's resident
// memory (and the time limit) instead.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define FULGUR_VDB_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define FULGUR_VDB_SANITIZED 1
#endif
#endif
#ifndef FULGUR_VDB_SANITIZED
#define FULGUR_VDB_SANITIZED 0
#endif

namespace fulgur::cloud::detail::vdb {

constexpr std::size_t kMaxNameBytes = 256;     // grid names, type names, map type names
constexpr std::uint32_t kMaxGrids = 4096;      // grids per file
constexpr std::size_t kMaxReasonBytes = 1024;  // an error text the child sends
constexpr std::size_t kReasonCut = 400;        // ... as the parent passes it on

// Beyond the load's budget, the child may use this much for the library itself (its
// decompression buffers, streams, the allocator's slack). Sanitized builds hold freed memory
// in a quarantine and count shadow pages in the resident size: they get more.
constexpr std::uint64_t kLibraryBytes = std::uint64_t(FULGUR_VDB_SANITIZED ? 1024 : 256) << 20;
// Until the descriptors are read and checked, the child may use at most this much beyond the
// library's share (and never more than the load's budget): a file's metadata, names and
// transforms are at most its own bytes, read once and copied a few times. A corrupt length
// prefix (a grid type "name" of 1 GB in a 52 KB file) then fails in milliseconds instead of
// filling the scene's whole memory budget (7.3 GB measured) before it is refused.
constexpr std::uint64_t descriptor_budget(std::uint64_t file_bytes, std::uint64_t budget) {
    const std::uint64_t want = (std::uint64_t(16) << 20) + 4 * file_bytes;
    return want < budget ? want : budget;
}
// The child's exit statuses of its own (0: done, or stopped where the parent refuses anyway).
constexpr int kExitOutOfMemory = 75;  // std::bad_alloc: its memory limit was reached
constexpr int kExitWriteFailed = 74;  // the pipe closed: the parent stopped listening

// Record tags, child -> parent.
enum Tag : std::uint8_t {
    kFacts = 'F',       // u32 count, then each grid (send_facts)
    kError = 'E',       // u8 about (file, chosen grid, named grid), string grid, string reason
    kBackground = 'B',  // f32
    kActiveBox = 'A',   // u8 empty, i32 x 6 (min, max)
    kLeaf = 'L',        // i32 x 3 origin, f32 x 512 (x-major: offset x << 6 | y << 3 | z)
    kTile = 'T',        // i32 x 3 origin, i32 edge (8, 128 or 4096 voxels), f32 value
    kDone = 'D',
};

// The float tree's node sizes as the records carry them (OpenVDB's standard 5-4-3 FloatTree;
// vdb_child.cpp checks them against it): a leaf's edge and value count, and the edges of the
// tiles of the lower and upper internal nodes.
constexpr int kLeafEdge = 8;
constexpr int kLeafValues = kLeafEdge * kLeafEdge * kLeafEdge;
constexpr int kLowerEdge = 128;
constexpr int kUpperEdge = 4096;

// An inclusive box of voxel indices (OpenVDB's CoordBBox, as plain numbers).
struct Box {
    std::array<std::int32_t, 3> min{0, 0, 0}, max{0, 0, 0};

    // Empty: min > max along some axis.
    bool empty() const { return min[0] > max[0] || min[1] > max[1] || min[2] > max[2]; }
    // Whether `b` lies inside this box (CoordBBox::isInside).
    bool contains(const Box& b) const {
        for (int a = 0; a < 3; ++a)
            if (b.min[a] < min[a] || b.max[a] > max[a]) return false;
        return true;
    }
    // "[x, y, z] -> [x, y, z]", as OpenVDB prints a CoordBBox.
    std::string text() const {
        auto corner = [](const std::array<std::int32_t, 3>& c) {
            return "[" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + "]";
        };
        return corner(min) + " -> " + corner(max);
    }
};

// What the child reads of a grid without its voxels: plain values, checked by the parent.
struct GridFacts {
    std::string name, value_type, map_type;
    bool float_grid = false;  // openvdb::FloatGrid (float values, the standard 5-4-3 tree)
    bool linear = false;      // the transform is linear: m below is its matrix
    bool has_bbox_min = false, has_bbox_max = false, has_count = false, has_mem = false;
    std::int32_t bbox_min[3] = {0, 0, 0}, bbox_max[3] = {0, 0, 0};
    std::int64_t count = 0, mem = 0;  // file_voxel_count, file_mem_bytes
    // Index -> world in OpenVDB's row-vector convention: row r (r < 3) is the image of index
    // axis r (the Jacobian), row 3 the translation.
    double m[4][3] = {};
};

inline std::string in_quotes(const std::string& s) { return "\"" + s + "\""; }

// Text from the file or from OpenVDB, for a message: at most `n` bytes, control characters
// replaced (an exception text of a corrupt file can be hundreds of megabytes of its bytes).
inline std::string cut(std::string_view s, std::size_t n = 300) {
    std::string r;
    for (const char c : s.substr(0, n)) r += (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) ? '?' : c;
    if (s.size() > n) r += "... (" + std::to_string(s.size()) + " bytes)";
    return r;
}

inline std::uint64_t add_saturated(std::uint64_t a, std::uint64_t b) {
    return a > std::numeric_limits<std::uint64_t>::max() - b ? std::numeric_limits<std::uint64_t>::max() : a + b;
}

// Field `field` (0: size, 1: resident) of /proc/<pid>/statm (pid 0: this process), in bytes;
// 0 when unreadable.
std::uint64_t statm_bytes(pid_t pid, int field);

}  // namespace fulgur::cloud::detail::vdb
