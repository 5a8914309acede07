// fulgur::core — NRRD (attached header + raw float32) import and export of voxel grids.
#pragma once

#include "core/grid.h"

#include <cstdint>
#include <filesystem>
#include <string_view>

namespace fulgur::core {

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

}  // namespace fulgur::core
