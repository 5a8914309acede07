// libFuzzer harness: the sun/sky light-file reader (sky::read_light_file, the .fgl caches) on
// arbitrary bytes, through a memory-backed regular file (it takes a path and checks it is a
// regular file of bounded size). Read twice: as any light file, and against a small lighting
// grid's shape (the corpus's 4 x 3 x 2 grid of 100 m voxels, 6 axis directions, "single" and
// "multiple"), as sky::load_or_solve reads a cache.
//
// The file ends with a CRC-32 of everything before it, and its key's hash must match its
// description: a mutated input would almost always stop there, so the harness makes both
// match before reading (a stored key hash at bytes 12-19 over the description its length at
// 20-23 announces, the CRC in the last 4 bytes). The mismatches themselves are tested in
// tests/sky/test_sky_cache.cpp.
#include "basis/basis.h"
#include "sky/sky.h"

#include <sys/mman.h>
#include <unistd.h>
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

namespace {

void make_checks_match(std::vector<std::uint8_t>& b) {
    constexpr std::size_t kHashAt = 12, kLengthAt = 20, kDescriptionAt = 24;
    if (b.size() >= kDescriptionAt + 4) {
        std::uint32_t len;
        std::memcpy(&len, b.data() + kLengthAt, 4);
        if (len <= b.size() - 4 - kDescriptionAt) {
            const std::uint64_t h = fulgur::basis::hash_description(
                std::string_view(reinterpret_cast<const char*>(b.data() + kDescriptionAt), len));
            std::memcpy(b.data() + kHashAt, &h, 8);
        }
    }
    if (b.size() >= 4) {
        const std::uint32_t crc = std::uint32_t(::crc32(::crc32(0L, Z_NULL, 0), b.data(), uInt(b.size() - 4)));
        std::memcpy(b.data() + b.size() - 4, &crc, 4);
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const int fd = ::memfd_create("fuzz.fgl", 0);
    static const std::string path = "/proc/self/fd/" + std::to_string(fd);
    static const fulgur::sky::LightFileShape shape = [] {
        fulgur::sky::LightFileShape s;
        s.grid.dims = {4, 3, 2};
        s.grid.voxel_size = 100.0;
        s.directions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        s.names = {"single", "multiple"};
        return s;
    }();
    if (size > (std::size_t(1) << 20)) return 0;  // libFuzzer's -max_len keeps inputs far below
    std::vector<std::uint8_t> bytes(data, data + size);
    make_checks_match(bytes);
    if (fd < 0 || ::ftruncate(fd, 0) != 0 || ::pwrite(fd, bytes.data(), bytes.size(), 0) != ssize_t(bytes.size()))
        std::abort();
    try {
        (void)fulgur::sky::read_light_file(path);
    } catch (const fulgur::core::Error&) {}
    try {
        (void)fulgur::sky::read_light_file(path, nullptr, &shape);
    } catch (const fulgur::core::Error&) {}
    return 0;
}
