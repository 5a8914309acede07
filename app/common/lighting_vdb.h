// A scene's density and a lighting field S as one .vdb (the tools' --vdb outputs): the density
// at full resolution and S on the lighting grid, one grid per output direction, world
// transforms in metres, metadata naming units, scene and direction.
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace fulgur::app {

struct LightingVdb {
    std::string scene;        ///< the scene's name and file, stored as file metadata
    double extinction = 0.0;  ///< kappa (1/m per unit density), stored with the density
    const core::Grid3<float>* density = nullptr;
    /// S per output direction (same lighting-grid geometry), and each direction (unit).
    std::vector<core::Grid3<float>> source;
    std::vector<glm::dvec3> directions;
    std::string source_meaning;  ///< what S is ("the frame at t = ..."), stored with each S grid
};

/// Writes `path` atomically: grid "density" (fog volume) and "S_00", "S_01", ... (one per
/// direction: S depends on the direction light leaves in when g != 0, and a mean over
/// directions would hide the forward peak a renderer needs; a g = 0 bake has one direction).
void write_lighting_vdb(const std::filesystem::path& path, const LightingVdb& v);

}  // namespace fulgur::app
