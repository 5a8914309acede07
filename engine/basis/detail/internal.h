// Internal to fulgur::basis (tests may include it): helpers shared by the .cpp files and
// the byte layout of the .fgb file (docs/fgb-format.md), so the corruption tests can patch
// checksums and reach the validation behind them.
#pragma once

#include "basis/compression.h"

#include <cstdint>
#include <span>

namespace fulgur::basis {

/// Correctly rounded (nearest, ties to even) binary16 from a double; same policy as
/// float_to_half (overflow -> infinity).
std::uint16_t double_to_half(double v) noexcept;

/// Puts a basis' coefficients in the canonical order (CompressedBasis: decreasing |value|,
/// ties by increasing index).
void sort_canonical(CompressedBasis& b);

/// CRC-32 (zlib's polynomial) of the bytes.
std::uint32_t crc32_of(std::span<const std::uint8_t> bytes) noexcept;

namespace fgb {

inline constexpr std::uint8_t kMagic[8] = {0x89, 'F', 'G', 'B', '\r', '\n', 0x1a, '\n'};
inline constexpr std::uint32_t kEndianMarker = 0x01020304u;  // stored as 04 03 02 01
inline constexpr std::uint32_t kBlockMagic = 0x4c424746u;    // "FGBL" on disk
inline constexpr std::uint32_t kFlagPartial = 1u;
inline constexpr std::size_t kMaxDirections = 64;

// Fixed header, byte offsets.
inline constexpr std::size_t kOffMagic = 0;
inline constexpr std::size_t kOffVersion = 8;
inline constexpr std::size_t kOffEndian = 12;
inline constexpr std::size_t kOffFileSize = 16;
inline constexpr std::size_t kOffSceneHash = 24;
inline constexpr std::size_t kOffFlags = 32;
inline constexpr std::size_t kOffLightCount = 36;
inline constexpr std::size_t kOffLightBegin = 40;
inline constexpr std::size_t kOffLightEnd = 44;
inline constexpr std::size_t kOffMetaOffset = 48;
inline constexpr std::size_t kOffMetaSize = 56;
inline constexpr std::size_t kOffIndexOffset = 64;
inline constexpr std::size_t kOffIndexSize = 72;
inline constexpr std::size_t kOffBlocksOffset = 80;
inline constexpr std::size_t kOffBlocksSize = 88;
inline constexpr std::size_t kOffHeaderCrc = 96;
inline constexpr std::size_t kOffReserved = 100;
inline constexpr std::size_t kHeaderSize = 104;

// Index entry: u64 offset, u64 size, u32 crc, u32 light.
inline constexpr std::size_t kIndexEntrySize = 24;
inline constexpr std::size_t kEntryOffCrc = 16;

// Block: u32 magic, u32 light, u32 n_dir, then per direction a 24-byte record
// (u32 count, i32 scale_exp, f64 gamma, f64 norm), then the coefficients: per direction
// indices and values (Entropy::None), or u32 stream size + a zlib stream (Entropy::Deflate).
inline constexpr std::size_t kBlockHeaderSize = 12;
inline constexpr std::size_t kBlockDirRecordSize = 24;

/// Deflate stream: the largest expansion zlib can produce is 1032:1; a stream size claiming
/// more than this per compressed byte is rejected before anything is allocated.
inline constexpr std::uint64_t kMaxInflateRatio = 1032;

/// Header CRC of a whole file image (bytes [0, blocks_offset) with the CRC field as zero).
std::uint32_t header_crc(std::span<const std::uint8_t> file, std::uint64_t blocks_offset) noexcept;

}  // namespace fgb
}  // namespace fulgur::basis
