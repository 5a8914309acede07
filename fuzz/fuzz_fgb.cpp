// libFuzzer harness: the .fgb reader (header, index, every block) on arbitrary bytes.
//
// Every byte of a .fgb is under a CRC (the header's over header, metadata and index; each
// block's in its index entry), and the header states the file's size: a mutated input would
// almost always stop at one of those checks. So the harness first makes them match what the
// input holds (the file size, each index entry's block CRC where the entry's range lies in
// the input, then the header CRC), and the mutations reach the metadata, the index and the
// blocks' decoding. The mismatches themselves are tested in tests/basis (test_fgb).
#include "basis/basis.h"
#include "basis/detail/fgb_codec.h"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace {

namespace fgb = fulgur::basis::fgb;
using fgb::peek;
using fgb::poke;

void make_checks_match(std::vector<std::uint8_t>& b) {
    if (b.size() < fgb::kHeaderSize) return;
    const std::uint64_t size = b.size();
    poke(b, fgb::kOffFileSize, size);
    const auto index_offset = peek<std::uint64_t>(b.data() + fgb::kOffIndexOffset);
    const auto index_size = peek<std::uint64_t>(b.data() + fgb::kOffIndexSize);
    if (index_offset <= size && index_size <= size - index_offset)
        for (std::uint64_t e = index_offset; e + fgb::kIndexEntrySize <= index_offset + index_size;
             e += fgb::kIndexEntrySize) {
            const auto offset = peek<std::uint64_t>(b.data() + e);
            const auto n = peek<std::uint64_t>(b.data() + e + 8);
            if (offset <= size && n <= size - offset)
                poke(b, std::size_t(e + 16),
                     fulgur::basis::crc32_of(std::span<const std::uint8_t>(b.data() + offset, std::size_t(n))));
        }
    poke(b, fgb::kOffHeaderCrc, fgb::header_crc(b, peek<std::uint64_t>(b.data() + fgb::kOffBlocksOffset)));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    std::vector<std::uint8_t> bytes(data, data + size);
    make_checks_match(bytes);
    try {
        fulgur::basis::FgbReader r(std::move(bytes), "fuzz.fgb");
        (void)fulgur::basis::load_fgb(r, {});
    } catch (const fulgur::core::Error&) {}
    return 0;
}
