// The .fgb codec: the fixed header, the metadata record and the per-light blocks, each
// encoder beside its decoder, plus the checksums and the scene-key hash. Byte layout in
// docs/fgb-format.md and basis/detail/internal.h. Decoders treat every byte as hostile: each
// count is bounded by the bytes that remain before anything is allocated, and every error
// names the file, the byte offset and the field.
#include "basis/detail/fgb_codec.h"

#include "basis/fgb.h"
#include "basis/half.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace fulgur::basis {

static_assert(std::endian::native == std::endian::little, "the .fgb writer and reader assume a little-endian host");

std::uint32_t crc32_of(std::span<const std::uint8_t> bytes) noexcept {
    uLong crc = ::crc32(0L, Z_NULL, 0);
    const std::uint8_t* p = bytes.data();
    std::size_t n = bytes.size();
    while (n > 0) {  // zlib takes uInt lengths
        const uInt chunk = uInt(std::min<std::size_t>(n, 1u << 30));
        crc = ::crc32(crc, p, chunk);
        p += chunk;
        n -= chunk;
    }
    return std::uint32_t(crc);
}

std::uint64_t hash_description(std::string_view text) noexcept {
    std::uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a 64
    for (char ch : text) {
        h ^= std::uint8_t(ch);
        h *= 0x100000001b3ull;
    }
    h ^= h >> 30;  // SplitMix64 finalizer: spreads FNV's weak high bits
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    h ^= h >> 31;
    return h;
}

BakeKey BakeKey::from_description(std::string description) {
    BakeKey k;
    k.hash = hash_description(description);
    k.description = std::move(description);
    return k;
}

void validate(const FgbMetadata& m, std::string_view where) {
    const std::string w(where);
    core::validate_geometry(m.lighting, w + ".lighting");
    if (m.lighting.cell_count() > kMaxFgbCells)
        throw core::Error(w + ".lighting", "more than " + std::to_string(kMaxFgbCells) + " cells");
    if (m.directions.empty() || m.directions.size() > fgb::kMaxDirections)
        throw core::Error(w + ".directions", "needs 1 to 64 directions, got " + std::to_string(m.directions.size()));
    for (std::size_t i = 0; i < m.directions.size(); ++i) {
        const glm::dvec3& d = m.directions[i];
        const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        if (!(std::fabs(len - 1.0) <= 1e-9))
            throw core::Error(w + ".directions[" + std::to_string(i) + "]", "not a unit vector");
    }
    const std::vector<double>* axes[3] = {&m.lights.x, &m.lights.y, &m.lights.z};
    for (int a = 0; a < 3; ++a) {
        if (axes[a]->empty()) throw core::Error(w + ".lights", "every axis needs at least one virtual light");
        for (std::size_t i = 0; i < axes[a]->size(); ++i) {
            if (!std::isfinite((*axes[a])[i]) || (i > 0 && !((*axes[a])[i] > (*axes[a])[i - 1])))
                throw core::Error(w + ".lights", "coordinates must be finite and increasing");
        }
    }
    if (m.lights.count() > kMaxVirtualLights) throw core::Error(w + ".lights", "too many virtual lights");
    if (m.lights.base_layer >= m.lights.z.size()) throw core::Error(w + ".lights.base_layer", "outside the z layers");
    if (!std::isfinite(m.lights.cloud_base) || !std::isfinite(m.lights.cloud_top))
        throw core::Error(w + ".lights", "cloud base and top must be finite");
    if (m.content < 1 || m.content > 3)
        throw core::Error(w + ".content", "mask " + std::to_string(m.content) + ", expected 1, 2 or 3");
    if (m.components < 1 || m.components > 2 || (m.components == 2 && m.content != 3))
        throw core::Error(w + ".components",
                          std::to_string(m.components) + ", expected 1, or 2 with content 3 (single and multiple)");
    validate(m.compression, w + ".compression");
    if (m.key.description.size() > fgb::kMaxDescription)
        throw core::Error(w + ".key", "description longer than 16 MiB");
}

namespace fgb {

std::string hex64(std::uint64_t v) {
    char buf[24];
    std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
    return buf;
}
std::string hex32(std::uint32_t v) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%08x", v);
    return buf;
}

std::string describe_range(std::uint32_t a, std::uint32_t b) {
    return "[" + std::to_string(a) + ", " + std::to_string(b) + ")";
}

namespace {

std::size_t value_bytes(Precision p) { return p == Precision::Float16 ? 2 : 4; }

std::uint16_t half_bits(float v, int scale_exp) {
    const std::uint16_t h = float_to_half(std::ldexp(v, -scale_exp));
    FULGUR_ASSERT((h & 0x7c00u) != 0x7c00u,
                  "encode_block: value not representable in float16 (not compressed for float16?)");
    return h;
}

}  // namespace

// ---- header ------------------------------------------------------------------------------

std::vector<std::uint8_t> encode_header(const Header& h) {
    std::vector<std::uint8_t> b(fgb::kHeaderSize, 0);
    std::memcpy(b.data(), fgb::kMagic, 8);
    poke(b, fgb::kOffVersion, h.version);
    poke(b, fgb::kOffEndian, h.endian);
    poke(b, fgb::kOffFileSize, h.file_size);
    poke(b, fgb::kOffSceneHash, h.scene_hash);
    poke(b, fgb::kOffFlags, h.flags);
    poke(b, fgb::kOffLightCount, h.light_count);
    poke(b, fgb::kOffLightBegin, h.light_begin);
    poke(b, fgb::kOffLightEnd, h.light_end);
    poke(b, fgb::kOffMetaOffset, h.meta_offset);
    poke(b, fgb::kOffMetaSize, h.meta_size);
    poke(b, fgb::kOffIndexOffset, h.index_offset);
    poke(b, fgb::kOffIndexSize, h.index_size);
    poke(b, fgb::kOffBlocksOffset, h.blocks_offset);
    poke(b, fgb::kOffBlocksSize, h.blocks_size);
    poke(b, fgb::kOffHeaderCrc, h.header_crc);
    poke(b, fgb::kOffReserved, h.reserved);
    return b;
}

Header decode_header(std::span<const std::uint8_t> head) {
    FULGUR_ASSERT(head.size() >= kHeaderSize, "decode_header: needs the whole fixed header");
    const std::uint8_t* p = head.data();
    Header h;
    h.version = peek<std::uint32_t>(p + kOffVersion);
    h.endian = peek<std::uint32_t>(p + kOffEndian);
    h.file_size = peek<std::uint64_t>(p + kOffFileSize);
    h.scene_hash = peek<std::uint64_t>(p + kOffSceneHash);
    h.flags = peek<std::uint32_t>(p + kOffFlags);
    h.light_count = peek<std::uint32_t>(p + kOffLightCount);
    h.light_begin = peek<std::uint32_t>(p + kOffLightBegin);
    h.light_end = peek<std::uint32_t>(p + kOffLightEnd);
    h.meta_offset = peek<std::uint64_t>(p + kOffMetaOffset);
    h.meta_size = peek<std::uint64_t>(p + kOffMetaSize);
    h.index_offset = peek<std::uint64_t>(p + kOffIndexOffset);
    h.index_size = peek<std::uint64_t>(p + kOffIndexSize);
    h.blocks_offset = peek<std::uint64_t>(p + kOffBlocksOffset);
    h.blocks_size = peek<std::uint64_t>(p + kOffBlocksSize);
    h.header_crc = peek<std::uint32_t>(p + kOffHeaderCrc);
    h.reserved = peek<std::uint32_t>(p + kOffReserved);
    return h;
}

std::uint32_t header_crc(std::span<const std::uint8_t> file, std::uint64_t blocks_offset) noexcept {
    if (blocks_offset > file.size() || blocks_offset < kHeaderSize) return 0;
    uLong crc = ::crc32(0L, Z_NULL, 0);
    const std::uint8_t zero[4] = {0, 0, 0, 0};
    crc = ::crc32(crc, file.data(), uInt(kOffHeaderCrc));
    crc = ::crc32(crc, zero, 4);
    const std::span<const std::uint8_t> rest =
        file.subspan(kOffHeaderCrc + 4, std::size_t(blocks_offset) - kOffHeaderCrc - 4);
    const std::uint32_t tail = crc32_of(rest);
    // Combine without re-reading: crc32_combine(crc(A), crc(B), len(B)).
    return std::uint32_t(::crc32_combine(crc, tail, z_off_t(rest.size())));
}

// ---- metadata ----------------------------------------------------------------------------

std::vector<std::uint8_t> encode_metadata(const FgbMetadata& m) {
    ByteWriter w;
    w.put(std::uint32_t(m.key.description.size()));
    w.put_bytes(m.key.description.data(), m.key.description.size());
    w.put(std::int32_t(m.lighting.dims.x));
    w.put(std::int32_t(m.lighting.dims.y));
    w.put(std::int32_t(m.lighting.dims.z));
    w.put(m.lighting.voxel_size);
    w.put(m.lighting.origin.x);
    w.put(m.lighting.origin.y);
    w.put(m.lighting.origin.z);
    w.put(std::uint32_t(m.directions.size()));
    for (const glm::dvec3& d : m.directions) {
        w.put(d.x);
        w.put(d.y);
        w.put(d.z);
    }
    w.put(m.content);
    w.put(m.components);
    const std::vector<double>* axes[3] = {&m.lights.x, &m.lights.y, &m.lights.z};
    for (const auto* a : axes) w.put(std::uint32_t(a->size()));
    for (const auto* a : axes)
        for (double v : *a) w.put(v);
    w.put(m.lights.cloud_base);
    w.put(m.lights.cloud_top);
    w.put(std::uint32_t(m.lights.base_layer));
    w.put(std::uint32_t(m.compression.mode));
    w.put(m.compression.xi);
    w.put(std::uint32_t(m.compression.precision));
    w.put(std::uint32_t(m.compression.decomposition));
    w.put(std::uint32_t(m.index_bytes()));
    w.put(std::uint32_t(m.compression.entropy));
    return w.bytes;
}

FgbMetadata decode_metadata(ByteReader& r, std::uint64_t scene_hash, const std::string& name) {
    FgbMetadata m;
    m.key.hash = scene_hash;
    const std::uint32_t dlen = r.count("metadata.description length", 1, kMaxDescription);
    const std::uint8_t* d = r.take(dlen, "metadata.description");
    m.key.description.assign(reinterpret_cast<const char*>(d), dlen);

    const std::uint64_t geom_at = r.offset();
    m.lighting.dims.x = r.get<std::int32_t>("metadata.lighting.nx");
    m.lighting.dims.y = r.get<std::int32_t>("metadata.lighting.ny");
    m.lighting.dims.z = r.get<std::int32_t>("metadata.lighting.nz");
    m.lighting.voxel_size = r.get<double>("metadata.lighting.voxel_size");
    m.lighting.origin.x = r.get<double>("metadata.lighting.origin.x");
    m.lighting.origin.y = r.get<double>("metadata.lighting.origin.y");
    m.lighting.origin.z = r.get<double>("metadata.lighting.origin.z");
    core::validate_geometry(m.lighting, name + " (byte " + std::to_string(geom_at) + ") metadata.lighting");
    if (m.lighting.cell_count() > kMaxFgbCells)
        throw core::Error(name + " (byte " + std::to_string(geom_at) + ")",
                          "metadata.lighting: " + std::to_string(m.lighting.cell_count()) +
                              " cells, the format allows " + std::to_string(kMaxFgbCells));

    const std::uint32_t ndir = r.count("metadata.direction count", 24, std::uint32_t(fgb::kMaxDirections));
    if (ndir == 0) r.fail("metadata.direction count", "must be at least 1");
    m.directions.resize(ndir);
    for (std::uint32_t i = 0; i < ndir; ++i) {
        const std::string f = "metadata.direction[" + std::to_string(i) + "]";
        const std::uint64_t at = r.offset();
        glm::dvec3& v = m.directions[i];
        v.x = r.get_finite(f + ".x");
        v.y = r.get_finite(f + ".y");
        v.z = r.get_finite(f + ".z");
        const double len = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
        if (!(std::fabs(len - 1.0) <= 1e-9))
            throw core::Error(name + " (byte " + std::to_string(at) + ")",
                              f + ": not a unit vector (length " + core::format_number(len, 17) + ")");
    }
    m.content = r.get<std::uint32_t>("metadata.content");
    if (m.content < 1 || m.content > 3)
        r.fail("metadata.content",
               "mask " + std::to_string(m.content) + ", expected 1 (single), 2 (multiple) or 3 (both)");
    m.components = r.get<std::uint32_t>("metadata.components");
    if (m.components < 1 || m.components > 2)
        r.fail("metadata.components", std::to_string(m.components) + ", expected 1 or 2");
    if (m.components == 2 && m.content != 3)
        r.fail("metadata.components",
               "2 separate components need content 3 (single and multiple), got " + std::to_string(m.content));

    std::uint32_t nl[3];
    const char* axis_names[3] = {"x", "y", "z"};
    std::uint64_t total = 1;
    for (int a = 0; a < 3; ++a) {
        nl[a] = r.count(std::string("metadata.virtual_lights.n") + axis_names[a], 8, std::uint32_t(kMaxVirtualLights));
        if (nl[a] == 0) r.fail(std::string("metadata.virtual_lights.n") + axis_names[a], "must be at least 1");
        total *= nl[a];
        if (total > kMaxVirtualLights)
            r.fail("metadata.virtual_lights", "more than " + std::to_string(kMaxVirtualLights) + " virtual lights");
    }
    std::vector<double>* axes[3] = {&m.lights.x, &m.lights.y, &m.lights.z};
    for (int a = 0; a < 3; ++a) {
        const std::string f = std::string("metadata.virtual_lights.") + axis_names[a];
        if (std::uint64_t(nl[a]) * 8 > r.remaining()) r.fail(f, "does not fit in the metadata");
        axes[a]->resize(nl[a]);
        for (std::uint32_t i = 0; i < nl[a]; ++i) {
            const std::uint64_t at = r.offset();
            (*axes[a])[i] = r.get_finite(f + "[" + std::to_string(i) + "]");
            if (i > 0 && !((*axes[a])[i] > (*axes[a])[i - 1]))
                throw core::Error(name + " (byte " + std::to_string(at) + ")", f + ": coordinates must increase");
        }
    }
    m.lights.cloud_base = r.get_finite("metadata.virtual_lights.cloud_base");
    m.lights.cloud_top = r.get_finite("metadata.virtual_lights.cloud_top");
    const std::uint32_t base_layer = r.get<std::uint32_t>("metadata.virtual_lights.base_layer");
    if (base_layer >= nl[2]) r.fail("metadata.virtual_lights.base_layer", "outside the z layers");
    m.lights.base_layer = base_layer;

    const std::uint32_t mode = r.get<std::uint32_t>("metadata.compression.threshold");
    if (mode > 2) r.fail("metadata.compression.threshold", "unknown mode " + std::to_string(mode));
    m.compression.mode = ThresholdMode(mode);
    m.compression.xi = r.get_finite("metadata.compression.xi");
    const std::uint32_t prec = r.get<std::uint32_t>("metadata.compression.precision");
    if (prec > 1) r.fail("metadata.compression.precision", "unknown precision " + std::to_string(prec));
    m.compression.precision = Precision(prec);
    const std::uint32_t dec = r.get<std::uint32_t>("metadata.compression.decomposition");
    if (dec > 1) r.fail("metadata.compression.decomposition", "unknown decomposition " + std::to_string(dec));
    m.compression.decomposition = Decomposition(dec);
    try {
        validate(m.compression, "metadata.compression");
    } catch (const core::Error& e) {
        r.fail(e.where(), e.reason());
    }
    const std::uint32_t ib = r.get<std::uint32_t>("metadata.index_bytes");
    if (int(ib) != m.index_bytes())
        r.fail("metadata.index_bytes",
               std::to_string(ib) + " does not match the grid (" + std::to_string(m.index_bytes()) + " expected)");
    const std::uint32_t ent = r.get<std::uint32_t>("metadata.compression.entropy");
    if (ent > 1) r.fail("metadata.compression.entropy", "unknown entropy coding " + std::to_string(ent));
    m.compression.entropy = Entropy(ent);
    if (r.remaining() != 0) r.fail("metadata", std::to_string(r.remaining()) + " unexpected bytes at the end");
    return m;
}

// ---- blocks ------------------------------------------------------------------------------

namespace {

void encode_plain(const CompressedLight& light, const FgbMetadata& m, bool f16, ByteWriter& w) {
    const std::size_t ib = std::size_t(m.index_bytes());
    for (const CompressedBasis& b : light.directions) {
        for (std::uint32_t idx : b.index) {
            if (ib == 2)
                w.put(std::uint16_t(idx));
            else
                w.put(idx);
        }
        for (float v : b.value) {
            if (f16) {
                w.put(half_bits(v, b.scale_exp));
            } else {
                w.put(v);
            }
        }
    }
}

template <class Fail>
void decode_plain(ByteReader& r, const std::vector<std::uint32_t>& counts, const FgbMetadata& m, CompressedLight& out,
                  const Fail& fail_at) {
    const std::size_t ib = std::size_t(m.index_bytes()), vb = value_bytes(m.compression.precision);
    const std::uint64_t cells = m.cells();
    std::uint64_t payload = 0;
    for (std::uint32_t c : counts) payload += std::uint64_t(c) * (ib + vb);
    if (payload != r.remaining())
        fail_at(r.offset(), "block size: the coefficient counts need " + std::to_string(payload) +
                                " bytes of indices and values, the block has " + std::to_string(r.remaining()));
    std::vector<std::uint32_t> sorted;  // duplicate check; sized by counts, which the block size bounds
    for (std::uint32_t d = 0; d < std::uint32_t(counts.size()); ++d) {
        CompressedBasis& b = out.directions[d];
        const std::uint32_t n = counts[d];
        const std::string f = "direction " + std::to_string(d);
        const std::uint64_t idx_at = r.offset();
        const std::uint8_t* ip = r.take(std::size_t(n) * ib, "indices");
        const std::uint64_t val_at = r.offset();
        const std::uint8_t* vp = r.take(std::size_t(n) * vb, "values");
        b.index.resize(n);
        b.value.resize(n);
        for (std::uint32_t k = 0; k < n; ++k) {
            const std::uint32_t idx =
                ib == 2 ? std::uint32_t(peek<std::uint16_t>(ip + 2 * k)) : peek<std::uint32_t>(ip + 4 * k);
            if (idx >= cells)
                fail_at(idx_at + k * ib, f + " coefficient " + std::to_string(k) + ": index " + std::to_string(idx) +
                                             " outside the " + std::to_string(cells) + " cells");
            b.index[k] = idx;
            float v;
            if (vb == 2) {
                const std::uint16_t h = peek<std::uint16_t>(vp + 2 * k);
                if ((h & 0x7c00u) == 0x7c00u)
                    fail_at(val_at + k * vb, f + " coefficient " + std::to_string(k) + ": float16 value is not finite");
                v = std::ldexp(half_to_float(h), b.scale_exp);
            } else {
                v = peek<float>(vp + 4 * k);
                if (!std::isfinite(v))
                    fail_at(val_at + k * vb, f + " coefficient " + std::to_string(k) + ": float32 value is not finite");
            }
            if (k > 0 && std::fabs(v) > std::fabs(b.value[k - 1]))
                fail_at(val_at + k * vb, f + " coefficient " + std::to_string(k) +
                                             ": magnitudes must not increase (the file stores them largest first)");
            b.value[k] = v;
        }
        sorted.assign(b.index.begin(), b.index.end());
        std::sort(sorted.begin(), sorted.end());
        const auto dup = std::adjacent_find(sorted.begin(), sorted.end());
        if (dup != sorted.end()) {
            const std::size_t k = std::size_t(std::find(b.index.begin(), b.index.end(), *dup) - b.index.begin());
            fail_at(idx_at, f + ": index " + std::to_string(*dup) + " appears twice (first as coefficient " +
                                std::to_string(k) + ")");
        }
    }
}

// Entropy::Deflate (docs/fgb-format.md): per basis the indices in increasing order as
// LEB128 gaps (first index, then index - previous - 1), then the values of all bases in
// the same order as byte planes, most significant byte first (sign and exponent bytes are
// highly repetitive, mantissa bytes are not: splitting them lets deflate model each), all
// deflated as one zlib stream at level 3 (paper configuration at 1%: 67.2 MB at level 3,
// 66.0 MB at 6 for 1.6x the time, 68.2 MB at 1).
void encode_deflated(const CompressedLight& light, bool f16, ByteWriter& w) {
    std::size_t total = 0;
    for (const CompressedBasis& b : light.directions) total += b.size();
    const std::size_t vb = f16 ? 2 : 4;
    std::vector<std::uint8_t> gaps;
    gaps.reserve(total * 2);
    std::vector<std::uint8_t> planes(total * vb);
    std::vector<std::uint32_t> order;
    std::size_t coef = 0;
    for (const CompressedBasis& b : light.directions) {
        order.resize(b.size());
        for (std::uint32_t k = 0; k < order.size(); ++k) order[k] = k;
        std::sort(order.begin(), order.end(),
                  [&](std::uint32_t a, std::uint32_t c) { return b.index[a] < b.index[c]; });
        std::uint64_t next = 0;
        for (std::uint32_t k : order) {
            FULGUR_ASSERT(b.index[k] >= next, "encode_block: a basis holds the same index twice");
            std::uint64_t gap = b.index[k] - next;
            next = std::uint64_t(b.index[k]) + 1;
            while (gap >= 0x80u) {
                gaps.push_back(std::uint8_t(gap | 0x80u));
                gap >>= 7;
            }
            gaps.push_back(std::uint8_t(gap));
            const std::uint32_t bits =
                f16 ? half_bits(b.value[k], b.scale_exp) : std::bit_cast<std::uint32_t>(b.value[k]);
            for (std::size_t p = 0; p < vb; ++p) planes[p * total + coef] = std::uint8_t(bits >> (8 * (vb - 1 - p)));
            ++coef;
        }
    }
    gaps.insert(gaps.end(), planes.begin(), planes.end());
    FULGUR_ASSERT(gaps.size() <= std::numeric_limits<std::uint32_t>::max(),
                  "encode_block: block too large for the format");
    uLongf packed = compressBound(uLong(gaps.size()));
    std::vector<std::uint8_t> z(packed);
    if (compress2(z.data(), &packed, gaps.data(), uLong(gaps.size()), 3) != Z_OK) throw std::bad_alloc();
    w.put(std::uint32_t(gaps.size()));
    w.put_bytes(z.data(), packed);
}

/// Reads one value of the byte planes (most significant plane first) and checks it.
/// Returns false (leaving v unset) for a value that is not finite.
inline bool plane_value(const std::uint8_t* planes, std::size_t plane_stride, std::size_t at, std::size_t vb,
                        int scale_exp, float& v) {
    std::uint32_t bits = 0;
    for (std::size_t p = 0; p < vb; ++p) bits = (bits << 8) | planes[p * plane_stride + at];
    if (vb == 2) {
        if ((bits & 0x7c00u) == 0x7c00u) return false;
        v = std::ldexp(half_to_float(std::uint16_t(bits)), scale_exp);
        return true;
    }
    v = std::bit_cast<float>(bits);
    return std::isfinite(v);
}

/// Entropy::Deflate: u32 stream size, then a zlib stream to the end of the block holding
/// every basis' index gaps (LEB128) followed by the value byte planes of all coefficients.
template <class Fail>
void decode_deflated(ByteReader& r, const std::vector<std::uint32_t>& counts, const FgbMetadata& m,
                     CompressedLight& out, bool canonical, const Fail& fail_at) {
    const std::size_t vb = value_bytes(m.compression.precision);
    const std::uint64_t cells = m.cells();
    std::uint64_t total = 0;
    for (std::uint32_t c : counts) total += c;
    const std::uint64_t size_at = r.offset();
    const std::uint32_t stream = r.get<std::uint32_t>("block.stream size");
    // Each gap takes 1..4 LEB128 bytes (indices < 2^26 < 2^28) and each value vb bytes.
    const std::uint64_t lo = total * (1 + vb), hi = total * (4 + vb);
    if (stream < lo || stream > hi)
        fail_at(size_at, "block.stream size: " + std::to_string(stream) + " bytes cannot hold " +
                             std::to_string(total) + " coefficients (" + std::to_string(lo) + " to " +
                             std::to_string(hi) + " expected)");
    const std::uint64_t packed = r.remaining();
    if (stream > packed * fgb::kMaxInflateRatio + 64)
        fail_at(size_at, "block.stream size: " + std::to_string(stream) + " bytes cannot come out of " +
                             std::to_string(packed) + " deflated bytes");
    if (packed > std::numeric_limits<uInt>::max())
        fail_at(size_at,
                "block.stream: " + std::to_string(packed) + " deflated bytes exceed the format's 4 GiB per block");
    const std::uint64_t data_at = r.offset();
    const std::uint8_t* src = r.take(std::size_t(packed), "block.stream");
    std::vector<std::uint8_t> buf(std::size_t(stream) + 1);  // + 1: zlib wants a non-null output even for 0 bytes
    {
        z_stream z{};
        if (inflateInit(&z) != Z_OK) throw std::bad_alloc();
        z.next_in = const_cast<Bytef*>(src);
        z.avail_in = uInt(packed);
        z.next_out = buf.data();
        z.avail_out = uInt(stream);
        const int rc = inflate(&z, Z_FINISH);
        const std::uint64_t in_used = z.total_in, out_made = z.total_out;
        inflateEnd(&z);
        if (rc != Z_STREAM_END || out_made != stream || in_used != packed)
            fail_at(
                data_at + in_used,
                "block.stream: the deflated coefficients are damaged (zlib: " +
                    std::string(rc == Z_STREAM_END   ? "ends with " + std::to_string(packed - in_used) + " bytes unread"
                                : rc == Z_BUF_ERROR  ? "more data than the stream size"
                                : rc == Z_DATA_ERROR ? "invalid data"
                                                     : "error " + std::to_string(rc)) +
                    ", " + std::to_string(out_made) + " of " + std::to_string(stream) + " bytes)");
    }
    // Offsets inside the inflated stream are reported relative to the stream's start.
    const std::uint64_t gaps_size = stream - total * vb;
    const std::uint8_t* planes = buf.data() + gaps_size;
    auto fail_in_stream = [&](std::uint64_t at, const std::string& what) {
        fail_at(data_at, "block.stream byte " + std::to_string(at) + ": " + what);
    };
    std::size_t pos = 0, coef = 0;
    for (std::size_t d = 0; d < counts.size(); ++d) {
        CompressedBasis& b = out.directions[d];
        const std::string f = "direction " + std::to_string(d);
        b.index.resize(counts[d]);
        b.value.resize(counts[d]);
        std::uint64_t next = 0;  // smallest index the next coefficient may have
        for (std::uint32_t k = 0; k < counts[d]; ++k, ++coef) {
            const std::size_t at = pos;
            std::uint64_t gap = 0;
            for (int shift = 0;; shift += 7) {
                if (pos >= gaps_size)
                    fail_in_stream(
                        at, f + " coefficient " + std::to_string(k) + ": index gaps run past their part of the stream");
                if (shift > 21)
                    fail_in_stream(at, f + " coefficient " + std::to_string(k) + ": index gap longer than 4 bytes");
                const std::uint8_t byte = buf[pos++];
                gap |= std::uint64_t(byte & 0x7fu) << shift;
                if (!(byte & 0x80u)) break;
            }
            const std::uint64_t idx = next + gap;
            if (idx >= cells)
                fail_in_stream(at, f + " coefficient " + std::to_string(k) + ": index " + std::to_string(idx) +
                                       " outside the " + std::to_string(cells) + " cells");
            b.index[k] = std::uint32_t(idx);
            next = idx + 1;
            if (!plane_value(planes, std::size_t(total), coef, vb, b.scale_exp, b.value[k]))
                fail_at(data_at, "block.stream, " + f + " coefficient " + std::to_string(k) + ": float" +
                                     std::to_string(8 * vb) + " value is not finite");
        }
        if (canonical) sort_canonical(b);
    }
    if (pos != gaps_size) fail_in_stream(pos, std::to_string(gaps_size - pos) + " bytes of index gaps left over");
}

}  // namespace

CompressedLight decode_block(const std::uint8_t* data, std::size_t size, std::uint64_t file_offset,
                             std::uint32_t expected_light, const FgbMetadata& m, const std::string& name,
                             bool canonical) {
    const std::string light_name = "light " + std::to_string(expected_light);
    ByteReader r(data, size, file_offset, name);
    auto fail_at = [&](std::uint64_t at, const std::string& what) -> void {
        throw core::Error(name + " (byte " + std::to_string(at) + ", " + light_name + ")", what);
    };
    const std::uint32_t magic = r.get<std::uint32_t>("block.magic");
    if (magic != fgb::kBlockMagic) fail_at(file_offset, "block.magic: " + hex32(magic) + " is not \"FGBL\"");
    const std::uint32_t light = r.get<std::uint32_t>("block.light");
    if (light != expected_light) fail_at(file_offset + 4, "block.light: the block says light " + std::to_string(light));
    const std::uint64_t ndir_at = r.offset();
    const std::uint32_t ndir = r.get<std::uint32_t>("block.basis count");
    if (ndir != m.bases())
        fail_at(ndir_at, "block.basis count: " + std::to_string(ndir) + ", the file has " + std::to_string(m.bases()) +
                             " bases (components x directions)");
    const std::uint64_t cells = m.cells();
    CompressedLight out;
    out.light = light;
    out.directions.resize(ndir);
    std::vector<std::uint32_t> counts(ndir);
    for (std::uint32_t d = 0; d < ndir; ++d) {
        const std::string f = "block.direction[" + std::to_string(d) + "].";
        const std::uint64_t at = r.offset();
        counts[d] = r.get<std::uint32_t>(f + "count");
        if (counts[d] > cells)
            fail_at(at, f + "count: " + std::to_string(counts[d]) + " coefficients, the grid has " +
                            std::to_string(cells) + " cells");
        CompressedBasis& b = out.directions[d];
        b.scale_exp = r.get<std::int32_t>(f + "scale_exp");
        if (m.compression.precision == Precision::Float32 ? b.scale_exp != 0
                                                          : (b.scale_exp < -125 || b.scale_exp > 112))
            fail_at(at + 4, f + "scale_exp: " + std::to_string(b.scale_exp) + " is out of range");
        // Legal for the format, but values up to 2^(scale_exp + 16) would overflow once lit.
        if (b.scale_exp + 16 > kMaxLitExponent)
            fail_at(at + 4, f + "scale_exp: " + std::to_string(b.scale_exp) + " allows coefficients up to 2^" +
                                std::to_string(b.scale_exp + 16) + ", beyond 2^" + std::to_string(kMaxLitExponent) +
                                ": they would overflow float32 once lit by a bolt");
        if (counts[d] == 0 && b.scale_exp != 0) fail_at(at + 4, f + "scale_exp: must be 0 for an empty basis");
        b.gamma = r.get<double>(f + "gamma");
        b.norm = r.get<double>(f + "norm");
        if (!std::isfinite(b.gamma) || b.gamma < 0.0) fail_at(at + 8, f + "gamma: not a finite value >= 0");
        if (!std::isfinite(b.norm) || b.norm < 0.0) fail_at(at + 16, f + "norm: not a finite value >= 0");
    }
    if (m.compression.entropy == Entropy::Deflate)
        decode_deflated(r, counts, m, out, canonical, fail_at);
    else
        decode_plain(r, counts, m, out, fail_at);
    const float lit_max = std::ldexp(1.0f, kMaxLitExponent);
    for (std::size_t d = 0; d < out.directions.size(); ++d)
        for (const float v : out.directions[d].value)
            if (!(std::fabs(v) <= lit_max))
                fail_at(file_offset, "block.direction[" + std::to_string(d) + "]: a coefficient of " +
                                         core::format_number(v) + " is beyond 2^" + std::to_string(kMaxLitExponent) +
                                         ": it would overflow float32 once lit by a bolt");
    return out;
}

}  // namespace fgb

EncodedBlock encode_block(const CompressedLight& light, const FgbMetadata& m) {
    FULGUR_ASSERT(light.directions.size() == m.bases(),
                  "encode_block: basis count differs from the file's (components x directions)");
    const bool f16 = m.compression.precision == Precision::Float16;
    fgb::ByteWriter w;
    w.put(fgb::kBlockMagic);
    w.put(light.light);
    w.put(std::uint32_t(light.directions.size()));
    for (const CompressedBasis& b : light.directions) {
        FULGUR_ASSERT(b.index.size() == b.value.size() && b.size() <= m.cells(), "encode_block: malformed basis");
        for (std::uint32_t idx : b.index)
            FULGUR_ASSERT(idx < m.cells(), "encode_block: coefficient index outside the grid");
        w.put(std::uint32_t(b.size()));
        w.put(std::int32_t(b.scale_exp));
        w.put(b.gamma);
        w.put(b.norm);
    }
    if (m.compression.entropy == Entropy::Deflate)
        fgb::encode_deflated(light, f16, w);
    else
        fgb::encode_plain(light, m, f16, w);
    EncodedBlock e;
    e.light = light.light;
    e.bytes = std::move(w.bytes);
    e.crc = crc32_of(e.bytes);
    return e;
}

}  // namespace fulgur::basis
