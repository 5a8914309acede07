// The .fgb reader: validates the fixed header, the section layout, the header CRC, the
// metadata and the index when opened, and each block's CRC and contents when read; and
// load_fgb(), which reads a whole bake. Never reads outside the file and never allocates from
// a size it has not bounded by the file size. Decoding is in fgb_codec.cpp.
#include "basis/detail/fgb_codec.h"
#include "basis/fgb.h"

#include <algorithm>
#include <cstring>
#include <fstream>

namespace fulgur::basis {

using fgb::describe_range;
using fgb::Header;
using fgb::hex32;
using fgb::hex64;
using fgb::peek;

struct FgbReader::Impl {
    std::string name;
    bool in_memory = false;
    std::vector<std::uint8_t> memory;  // whole file (memory reader)
    std::ifstream file;                // file reader
    std::uint64_t size = 0;
    Header h;
    std::vector<std::uint8_t> meta_bytes;
    FgbMetadata meta;
    struct Entry {
        std::uint64_t offset, size;
        std::uint32_t crc;
    };
    std::vector<Entry> entries;

    std::string at(std::uint64_t off) const { return name + " (byte " + std::to_string(off) + ")"; }

    std::vector<std::uint8_t> read(std::uint64_t offset, std::uint64_t n) {
        FULGUR_ASSERT(offset <= size && n <= size - offset, "fgb reader: read outside the file");
        std::vector<std::uint8_t> out(static_cast<std::size_t>(n));
        if (in_memory) {
            if (n) std::memcpy(out.data(), memory.data() + offset, std::size_t(n));
            return out;
        }
        file.clear();
        file.seekg(std::streamoff(offset));
        file.read(reinterpret_cast<char*>(out.data()), std::streamsize(n));
        if (!file || std::uint64_t(file.gcount()) != n)
            throw core::Error(at(offset),
                              "read of " + std::to_string(n) + " bytes failed (file changed or unreadable)");
        return out;
    }

    /// Validates the file when opened: the fixed header, the section layout, the header CRC,
    /// the light range, the metadata and the index, in that order.
    void open();
    void check_fixed_header(const std::vector<std::uint8_t>& head);
    void check_layout() const;
    std::vector<std::uint8_t> checked_region();
    std::uint64_t checked_light_range() const;
    void read_metadata(const std::vector<std::uint8_t>& region);
    void read_index(const std::vector<std::uint8_t>& region, std::uint64_t n);
    std::vector<std::uint8_t> checked_block(std::uint32_t l, std::uint64_t& offset);
};

void FgbReader::Impl::open() {
    using namespace fgb;
    if (size < kHeaderSize)
        throw core::Error(name, "truncated: the file has " + std::to_string(size) +
                                    " bytes, the fixed header alone is " + std::to_string(kHeaderSize));
    const std::vector<std::uint8_t> head = read(0, kHeaderSize);
    check_fixed_header(head);
    check_layout();
    const std::vector<std::uint8_t> region = checked_region();
    const std::uint64_t n = checked_light_range();
    read_metadata(region);
    read_index(region, n);
}

/// The fixed header: magic, version, endianness, file size, flags and the reserved field.
void FgbReader::Impl::check_fixed_header(const std::vector<std::uint8_t>& head) {
    using namespace fgb;
    if (std::memcmp(head.data(), kMagic, 8) != 0) {
        if (head[1] == 'F' && head[2] == 'G' && head[3] == 'B')
            throw core::Error(at(0),
                              "header.magic: damaged signature (line endings converted by a text-mode transfer?)");
        throw core::Error(at(0), "header.magic: not a Fulgur baked-basis (.fgb) file");
    }
    h = decode_header(head);
    if (h.version != kFgbVersion)
        throw core::Error(at(kOffVersion), "header.version: format version " + std::to_string(h.version) +
                                               ", this build reads version " + std::to_string(kFgbVersion) +
                                               "; rebake");
    if (h.endian != kEndianMarker)
        throw core::Error(at(kOffEndian), "header.endianness: marker " + hex32(h.endian) + ", expected " +
                                              hex32(kEndianMarker) + " (a little-endian file)");
    if (h.file_size != size)
        throw core::Error(at(kOffFileSize), std::string(size < h.file_size ? "truncated" : "wrong size") +
                                                ": header.file_size says " + std::to_string(h.file_size) +
                                                " bytes, the file has " + std::to_string(size));
    if (h.flags & ~kFlagPartial) throw core::Error(at(kOffFlags), "header.flags: unknown bits " + hex32(h.flags));
    if (h.reserved != 0) throw core::Error(at(kOffReserved), "header.reserved: must be 0");
}

/// Section layout: header | metadata | index | blocks, contiguous, ending at the file end.
void FgbReader::Impl::check_layout() const {
    using namespace fgb;
    // Each comparison is written so that no addition can overflow.
    if (h.meta_offset != kHeaderSize)
        throw core::Error(at(kOffMetaOffset), "header.meta_offset: " + std::to_string(h.meta_offset) + ", expected " +
                                                  std::to_string(kHeaderSize));
    if (h.meta_size > size - h.meta_offset)
        throw core::Error(at(kOffMetaSize),
                          "header.meta_size: " + std::to_string(h.meta_size) + " bytes run past the end of the file");
    if (h.index_offset != h.meta_offset + h.meta_size)
        throw core::Error(at(kOffIndexOffset), "header.index_offset: " + std::to_string(h.index_offset) +
                                                   ", the metadata ends at " +
                                                   std::to_string(h.meta_offset + h.meta_size));
    if (h.index_size > size - h.index_offset)
        throw core::Error(at(kOffIndexSize),
                          "header.index_size: " + std::to_string(h.index_size) + " bytes run past the end of the file");
    if (h.blocks_offset != h.index_offset + h.index_size)
        throw core::Error(at(kOffBlocksOffset), "header.blocks_offset: " + std::to_string(h.blocks_offset) +
                                                    ", the index ends at " +
                                                    std::to_string(h.index_offset + h.index_size));
    if (h.blocks_size != size - h.blocks_offset)
        throw core::Error(at(kOffBlocksSize), "header.blocks_size: " + std::to_string(h.blocks_size) +
                                                  ", the blocks span " + std::to_string(size - h.blocks_offset) +
                                                  " bytes to the end of the file");
}

/// Header, metadata and index (bytes [0, blocks_offset)), checked against the header CRC.
std::vector<std::uint8_t> FgbReader::Impl::checked_region() {
    using namespace fgb;
    // Header CRC over header + metadata + index (bounded by the file size above).
    std::vector<std::uint8_t> region = read(0, h.blocks_offset);
    const std::uint32_t crc = header_crc(region, h.blocks_offset);
    if (crc != h.header_crc)
        throw core::Error(at(kOffHeaderCrc), "header CRC mismatch: stored " + hex32(h.header_crc) + ", computed " +
                                                 hex32(crc) + " over bytes [0, " + std::to_string(h.blocks_offset) +
                                                 ") (header, metadata or index is corrupt)");
    return region;
}

/// The light range: the light count, the range and the partial flag, and the index size for
/// the range. Returns the number of lights in the file.
std::uint64_t FgbReader::Impl::checked_light_range() const {
    using namespace fgb;
    if (h.light_count == 0 || h.light_count > kMaxVirtualLights)
        throw core::Error(at(kOffLightCount),
                          "header.light_count: " + std::to_string(h.light_count) + " is out of range");
    if (!(h.light_begin < h.light_end && h.light_end <= h.light_count))
        throw core::Error(at(kOffLightBegin),
                          "header.light_begin/light_end: range " + describe_range(h.light_begin, h.light_end) +
                              " is empty or outside the " + std::to_string(h.light_count) + " lights");
    const bool complete = h.light_begin == 0 && h.light_end == h.light_count;
    if (complete == bool(h.flags & kFlagPartial))
        throw core::Error(at(kOffFlags), "header.flags: the partial flag contradicts the light range");
    const std::uint64_t n = h.light_end - h.light_begin;
    if (h.index_size != n * kIndexEntrySize)
        throw core::Error(at(kOffIndexSize), "header.index_size: " + std::to_string(h.index_size) + " bytes for " +
                                                 std::to_string(n) + " lights of " + std::to_string(kIndexEntrySize) +
                                                 " bytes each");
    return n;
}

/// The metadata, checked against the header's light count.
void FgbReader::Impl::read_metadata(const std::vector<std::uint8_t>& region) {
    using namespace fgb;
    meta_bytes.assign(region.begin() + std::ptrdiff_t(h.meta_offset), region.begin() + std::ptrdiff_t(h.index_offset));
    fgb::ByteReader mr(meta_bytes.data(), meta_bytes.size(), h.meta_offset, name);
    meta = fgb::decode_metadata(mr, h.scene_hash, name);
    if (meta.light_count() != h.light_count)
        throw core::Error(at(kOffLightCount), "header.light_count: " + std::to_string(h.light_count) +
                                                  ", the virtual-light grid in the metadata has " +
                                                  std::to_string(meta.light_count()));
}

/// The index of the n lights: every block inside the block section; together they tile it
/// without overlap.
void FgbReader::Impl::read_index(const std::vector<std::uint8_t>& region, std::uint64_t n) {
    using namespace fgb;
    entries.resize(std::size_t(n));
    struct Span {
        std::uint64_t offset, size;
        std::uint32_t light;
    };
    std::vector<Span> spans(static_cast<std::size_t>(n));
    for (std::uint64_t i = 0; i < n; ++i) {
        const std::uint64_t eo = h.index_offset + i * kIndexEntrySize;
        const std::uint8_t* e = region.data() + eo;
        Entry& en = entries[std::size_t(i)];
        en.offset = peek<std::uint64_t>(e);
        en.size = peek<std::uint64_t>(e + 8);
        en.crc = peek<std::uint32_t>(e + 16);
        const std::uint32_t light = peek<std::uint32_t>(e + 20);
        const std::uint32_t expected = h.light_begin + std::uint32_t(i);
        const std::string who = "index entry of light " + std::to_string(expected);
        if (light != expected) throw core::Error(at(eo + 20), who + ": names light " + std::to_string(light));
        if (en.offset < h.blocks_offset || en.offset > size)
            throw core::Error(at(eo), who + ": block offset " + std::to_string(en.offset) +
                                          " is outside the block section [" + std::to_string(h.blocks_offset) + ", " +
                                          std::to_string(size) + ")");
        if (en.size < kBlockHeaderSize || en.size > size - en.offset)
            throw core::Error(at(eo + 8), who + ": block size " + std::to_string(en.size) + " at offset " +
                                              std::to_string(en.offset) + " does not fit in the file");
        spans[std::size_t(i)] = {en.offset, en.size, expected};
    }
    std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) { return a.offset < b.offset; });
    std::uint64_t expect = h.blocks_offset;
    for (const Span& s : spans) {
        if (s.offset != expect)
            throw core::Error(at(s.offset), "block of light " + std::to_string(s.light) +
                                                (s.offset < expect ? " overlaps the previous block"
                                                                   : " leaves a gap after the previous block") +
                                                " (expected it at byte " + std::to_string(expect) + ")");
        expect = s.offset + s.size;
    }
    if (expect != size) throw core::Error(at(expect), "bytes after the last block are not indexed");
}

FgbReader::FgbReader(const std::filesystem::path& path) : impl_(std::make_unique<Impl>()) {
    impl_->name = path.string();
    const std::uint64_t sz = core::check_readable_file(path, kMaxFgbBytes, ".fgb");
    impl_->file.open(path, std::ios::binary);
    if (!impl_->file) throw core::Error(impl_->name, "cannot open baked file");
    impl_->size = sz;
    impl_->open();
}

FgbReader::FgbReader(std::vector<std::uint8_t> bytes, std::string name) : impl_(std::make_unique<Impl>()) {
    impl_->name = std::move(name);
    impl_->size = bytes.size();
    impl_->memory = std::move(bytes);
    impl_->in_memory = true;
    impl_->open();
}

FgbReader::~FgbReader() = default;
FgbReader::FgbReader(FgbReader&&) noexcept = default;
FgbReader& FgbReader::operator=(FgbReader&&) noexcept = default;

const FgbMetadata& FgbReader::metadata() const noexcept { return impl_->meta; }
std::uint32_t FgbReader::light_begin() const noexcept { return impl_->h.light_begin; }
std::uint32_t FgbReader::light_end() const noexcept { return impl_->h.light_end; }
bool FgbReader::partial() const noexcept { return impl_->h.flags & fgb::kFlagPartial; }
std::uint64_t FgbReader::file_size() const noexcept { return impl_->size; }
const std::string& FgbReader::name() const noexcept { return impl_->name; }

void FgbReader::check_metadata(const FgbMetadata& expected) const {
    check_key(expected.key);
    const FgbMetadata& have = impl_->meta;
    const std::string& n = impl_->name;
    auto refuse = [&](const std::string& field, const std::string& file_has, const std::string& plan_has) {
        throw core::Error(n + ": " + field,
                          "the file has " + file_has + ", the scene's plan has " + plan_has +
                              " (a header that does not match its own key: not a bake of this scene; rebake)");
    };
    auto dims = [](core::Int3 d) {
        return std::to_string(d.x) + "x" + std::to_string(d.y) + "x" + std::to_string(d.z);
    };
    auto vec = [](const glm::dvec3& v) {
        return "(" + core::format_number(v.x, 17) + ", " + core::format_number(v.y, 17) + ", " +
               core::format_number(v.z, 17) + ")";
    };
    if (have.lighting.dims != expected.lighting.dims)
        refuse("header.lighting.dims", dims(have.lighting.dims), dims(expected.lighting.dims));
    if (have.lighting.voxel_size != expected.lighting.voxel_size)
        refuse("header.lighting.voxel_size", core::format_number(have.lighting.voxel_size, 17),
               core::format_number(expected.lighting.voxel_size, 17));
    if (have.lighting.origin != expected.lighting.origin)
        refuse("header.lighting.origin", vec(have.lighting.origin), vec(expected.lighting.origin));
    if (have.directions != expected.directions)
        refuse("metadata.directions", std::to_string(have.directions.size()) + " directions",
               std::to_string(expected.directions.size()) + " (or different ones)");
    if (have.content != expected.content || have.components != expected.components)
        refuse("metadata.content",
               "content " + std::to_string(have.content) + " in " + std::to_string(have.components) + " component(s)",
               "content " + std::to_string(expected.content) + " in " + std::to_string(expected.components));
    if (!(have.lights == expected.lights))
        refuse("metadata.lights", std::to_string(have.lights.count()) + " virtual lights",
               std::to_string(expected.lights.count()) + " (or at other positions)");
    if (!(have.compression == expected.compression))
        refuse("metadata.compression", "other compression settings (decomposition, precision, threshold)",
               "the scene's");
}

std::string key_difference(const BakeKey& have, const BakeKey& expected) {
    if (have == expected) return {};
    // Name the first differing line of the canonical descriptions.
    auto lines = [](const std::string& s) {
        std::vector<std::string> v;
        std::size_t a = 0;
        while (a <= s.size()) {
            const std::size_t b = s.find('\n', a);
            if (b == std::string::npos) {
                if (a < s.size()) v.push_back(s.substr(a));
                break;
            }
            v.push_back(s.substr(a, b - a));
            a = b + 1;
        }
        return v;
    };
    const std::vector<std::string> f = lines(have.description), e = lines(expected.description);
    std::string diff;
    for (std::size_t i = 0; i < std::max(f.size(), e.size()); ++i) {
        const std::string fl = i < f.size() ? "\"" + f[i] + "\"" : "nothing";
        const std::string el = i < e.size() ? "\"" + e[i] + "\"" : "nothing";
        if (fl != el) {
            diff =
                "first difference at line " + std::to_string(i + 1) + ": the file has " + fl + ", the scene has " + el;
            break;
        }
    }
    if (diff.empty())
        diff = "the descriptions are identical, only the hashes differ (hash function changed?)";
    else if (hash_description(have.description) != have.hash)
        diff += " (the file's description does not hash to the file's own key: it was edited after the bake)";
    else if (have.hash == expected.hash)
        diff += " (equal hashes: a hash collision)";
    return diff;
}

void FgbReader::check_key(const BakeKey& expected) const {
    const BakeKey& have = impl_->meta.key;
    if (have == expected) return;
    throw core::Error(impl_->name, "stale bake: baked for scene hash " + hex64(have.hash) +
                                       ", the scene now hashes to " + hex64(expected.hash) + "; " +
                                       key_difference(have, expected) + "; rebake it");
}

/// Light l's block bytes after the CRC check (range, entry and CRC errors name the file).
std::vector<std::uint8_t> FgbReader::Impl::checked_block(std::uint32_t l, std::uint64_t& offset) {
    Impl& r = *this;
    if (l < r.h.light_begin || l >= r.h.light_end)
        throw core::Error(r.name, "light " + std::to_string(l) + " is not in this file's range " +
                                      describe_range(r.h.light_begin, r.h.light_end));
    const Entry& e = r.entries[l - r.h.light_begin];
    std::vector<std::uint8_t> bytes = r.read(e.offset, e.size);
    const std::uint32_t crc = crc32_of(bytes);
    if (crc != e.crc)
        throw core::Error(r.at(e.offset), "light " + std::to_string(l) + ": block CRC mismatch over bytes [" +
                                              std::to_string(e.offset) + ", " + std::to_string(e.offset + e.size) +
                                              "): stored " + hex32(e.crc) + ", computed " + hex32(crc));
    offset = e.offset;
    return bytes;
}

CompressedLight FgbReader::read_light(std::uint32_t l, Order order) {
    std::uint64_t offset = 0;
    const std::vector<std::uint8_t> bytes = impl_->checked_block(l, offset);
    return fgb::decode_block(bytes.data(), bytes.size(), offset, l, impl_->meta, impl_->name,
                             order == Order::Canonical);
}

std::uint64_t FgbReader::coefficient_count(std::uint32_t l) {
    std::uint64_t offset = 0;
    const std::vector<std::uint8_t> bytes = impl_->checked_block(l, offset);
    const std::size_t bases = impl_->meta.bases();
    const std::size_t need = fgb::kBlockHeaderSize + bases * fgb::kBlockDirRecordSize;
    if (bytes.size() < need)
        throw core::Error(impl_->at(offset), "light " + std::to_string(l) + ": block of " +
                                                 std::to_string(bytes.size()) + " bytes is shorter than its table (" +
                                                 std::to_string(need) + ")");
    std::uint64_t total = 0;
    for (std::size_t d = 0; d < bases; ++d)
        total += std::min<std::uint64_t>(
            peek<std::uint32_t>(bytes.data() + fgb::kBlockHeaderSize + d * fgb::kBlockDirRecordSize),
            impl_->meta.cells());
    return total;
}

EncodedBlock FgbReader::read_encoded(std::uint32_t l) {
    (void)read_light(l);  // full validation
    const Impl::Entry& e = impl_->entries[l - impl_->h.light_begin];
    EncodedBlock b;
    b.light = l;
    b.crc = e.crc;
    b.bytes = impl_->read(e.offset, e.size);
    return b;
}

std::size_t BakedBasis::coefficient_count() const noexcept {
    std::size_t n = 0;
    for (const CompressedLight& l : lights) n += l.coefficient_count();
    return n;
}

BakedBasis load_fgb(FgbReader& reader, const LoadOptions& options) {
    if (reader.partial())
        throw core::Error(reader.name(), "holds only lights " +
                                             describe_range(reader.light_begin(), reader.light_end()) + " of " +
                                             std::to_string(reader.metadata().light_count()) +
                                             " (a partial bake); merge the parts first");
    if (options.expected_key) reader.check_key(*options.expected_key);
    BakedBasis out;
    out.meta = reader.metadata();
    out.lights.reserve(out.meta.light_count());
    for (std::uint32_t l = 0; l < out.meta.light_count(); ++l) {
        out.lights.push_back(reader.read_light(l));
        if (options.retruncate)
            for (CompressedBasis& b : out.lights.back().directions)
                retruncate(b, options.retruncate_mode, options.retruncate_xi);
    }
    return out;
}

BakedBasis load_fgb(const std::filesystem::path& path, const LoadOptions& options) {
    FgbReader reader(path);
    return load_fgb(reader, options);
}

}  // namespace fulgur::basis
