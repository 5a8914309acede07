// Internal to fulgur::basis: the .fgb codec shared by the writer (fgb_writer.cpp) and the
// reader (fgb_reader.cpp): little-endian byte cursors, the fixed header, the metadata record
// and the per-light blocks, each encoded beside its decoder in fgb_codec.cpp. Byte layout:
// docs/fgb-format.md and basis/detail/internal.h.
#pragma once

#include "basis/detail/internal.h"
#include "basis/fgb.h"
#include "core/core.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace fulgur::basis::fgb {

/// Longest scene-key description a file may hold (bytes).
inline constexpr std::uint32_t kMaxDescription = 1u << 24;

/// "0x%016llx" / "0x%08x" of a hash or a CRC, for messages.
std::string hex64(std::uint64_t v);
std::string hex32(std::uint32_t v);
/// "[a, b)": a light range, for messages.
std::string describe_range(std::uint32_t a, std::uint32_t b);

// ---- little-endian serialization (the host is little-endian: fgb_codec.cpp checks) -------

class ByteWriter {
public:
    std::vector<std::uint8_t> bytes;
    template <class T>
    void put(T v) {
        static_assert(std::is_trivially_copyable_v<T>);
        const std::size_t at = bytes.size();
        bytes.resize(at + sizeof(T));
        std::memcpy(bytes.data() + at, &v, sizeof(T));
    }
    void put_bytes(const void* p, std::size_t n) {
        const std::size_t at = bytes.size();
        bytes.resize(at + n);
        if (n) std::memcpy(bytes.data() + at, p, n);
    }
};

template <class T>
void poke(std::vector<std::uint8_t>& b, std::size_t at, T v) {
    std::memcpy(b.data() + at, &v, sizeof(T));
}
template <class T>
T peek(const std::uint8_t* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return v;
}

/// A bounded cursor over bytes that sit at `base` in the file named `name`.
class ByteReader {
public:
    ByteReader(const std::uint8_t* data, std::size_t size, std::uint64_t base, const std::string& name)
        : p_(data), n_(size), base_(base), name_(name) {}

    std::uint64_t offset() const noexcept { return base_ + pos_; }
    std::size_t remaining() const noexcept { return n_ - pos_; }
    std::string where() const { return name_ + " (byte " + std::to_string(offset()) + ")"; }
    [[noreturn]] void fail(const std::string& field, const std::string& what) const {
        throw core::Error(where(), field + ": " + what);
    }

    template <class T>
    T get(const std::string& field) {
        if (remaining() < sizeof(T))
            fail(field, "needs " + std::to_string(sizeof(T)) + " bytes, only " + std::to_string(remaining()) +
                            " remain in this section (truncated or inconsistent sizes)");
        T v;
        std::memcpy(&v, p_ + pos_, sizeof(T));
        pos_ += sizeof(T);
        return v;
    }
    double get_finite(const std::string& field) {
        const std::uint64_t at = offset();
        const double v = get<double>(field);
        if (!std::isfinite(v)) throw core::Error(name_ + " (byte " + std::to_string(at) + ")", field + ": not finite");
        return v;
    }
    /// A count of items of `item_bytes` each that must fit in what remains.
    std::uint32_t count(const std::string& field, std::size_t item_bytes, std::uint32_t max_allowed) {
        const std::uint64_t at = offset();
        const std::uint32_t c = get<std::uint32_t>(field);
        if (c > max_allowed)
            throw core::Error(name_ + " (byte " + std::to_string(at) + ")",
                              field + ": " + std::to_string(c) + " exceeds the limit " + std::to_string(max_allowed));
        if (item_bytes && std::uint64_t(c) * item_bytes > remaining())
            throw core::Error(name_ + " (byte " + std::to_string(at) + ")",
                              field + ": " + std::to_string(c) + " items of " + std::to_string(item_bytes) +
                                  " bytes do not fit in the " + std::to_string(remaining()) + " bytes that remain");
        return c;
    }
    const std::uint8_t* take(std::size_t n, const std::string& field) {
        if (remaining() < n)
            fail(field, "needs " + std::to_string(n) + " bytes, " + std::to_string(remaining()) + " remain");
        const std::uint8_t* q = p_ + pos_;
        pos_ += n;
        return q;
    }

private:
    const std::uint8_t* p_;
    std::size_t n_;
    std::size_t pos_ = 0;
    std::uint64_t base_;
    const std::string& name_;
};

// ---- the fixed header ---------------------------------------------------------------------

struct Header {
    std::uint32_t version = kFgbVersion;
    std::uint64_t file_size = 0;
    std::uint64_t scene_hash = 0;
    std::uint32_t flags = 0;
    std::uint32_t light_count = 0, light_begin = 0, light_end = 0;
    std::uint64_t meta_offset = 0, meta_size = 0, index_offset = 0, index_size = 0, blocks_offset = 0, blocks_size = 0;
    std::uint32_t header_crc = 0;
    std::uint32_t endian = kEndianMarker;  ///< as stored; kEndianMarker in a valid file
    std::uint32_t reserved = 0;            ///< as stored; 0 in a valid file
};

/// The kHeaderSize bytes of a header (magic included).
std::vector<std::uint8_t> encode_header(const Header& h);
/// The fields of a header as stored, unchecked (the reader validates them in order);
/// `head` holds at least kHeaderSize bytes.
Header decode_header(std::span<const std::uint8_t> head);

// ---- the metadata record ------------------------------------------------------------------

std::vector<std::uint8_t> encode_metadata(const FgbMetadata& m);
/// Decodes and validates the metadata in `r` (all of it); errors name `name` and the byte.
FgbMetadata decode_metadata(ByteReader& r, std::uint64_t scene_hash, const std::string& name);

// ---- blocks (encode_block is public: basis/fgb.h) ------------------------------------------

/// Decodes and validates the block of light `expected_light` that sits at `file_offset` in
/// the file `name`. canonical: restore CompressedBasis' order (else as stored).
CompressedLight decode_block(const std::uint8_t* data, std::size_t size, std::uint64_t file_offset,
                             std::uint32_t expected_light, const FgbMetadata& m, const std::string& name,
                             bool canonical = true);

}  // namespace fulgur::basis::fgb
