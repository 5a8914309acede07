// Internal to fulgur::cloud: how a .vdb file's grid becomes the engine's density grid, decided
// on the grid descriptors alone (vdb_layout.cpp). Pure: the child runs inspect() to decide
// whether to read the tree, the parent again on the descriptors it received.
#pragma once

#include "cloud/cloud.h"
#include "cloud/detail/vdb_records.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace fulgur::cloud::detail::vdb {

// What inspect() learns, with the numbers load() needs.
struct Layout {
    VdbInfo info;
    Box bbox;                              // the file's active-voxel box (index space)
    int src_axis[3] = {0, 1, 2};           // engine axis a reads file axis src_axis[a] ...
    bool flip[3] = {false, false, false};  // ... reversed (y-up: the engine's y is the file's -z)
    glm::dvec3 source_origin{0.0};         // engine coordinates of the box's lower corner, metres
    std::uint64_t tree_bytes = 0;          // the sparse tree's share of info.load_bytes
};

// Asserts that the options' sizes are positive (0: default).
void check_options(const VdbImport& o);

// The choice of grid and every check that needs no voxel, on the descriptors alone; throws
// core::Error naming the file (or the grid) on a refusal.
Layout inspect(const std::vector<GridFacts>& grids, const std::filesystem::path& path, const VdbImport& o);

// "a x b x c".
std::string dims_text(core::Int3 d);

// "density (float), vel (vec3s)"; a long list is cut (a file may hold thousands of grids).
std::string list_grids(const std::vector<std::string>& grids);

}  // namespace fulgur::cloud::detail::vdb
