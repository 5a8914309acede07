// fulgur-shot --blender DIR: what Blender (Cycles) needs to render the frame fulgur-shot shows,
// in the units Fulgur computes in (docs/blender.md): DIR/frame.json and DIR/density.vdb.
#pragma once

#include "view/view.h"

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

namespace fulgur::app {

struct BlenderExport {
    std::string scene;  ///< the scene's name and file, for people
    std::string frame;  ///< what the frame is (seed, time, quality), for people
    render::Camera camera;
    int width = 0, height = 0;
    /// The channel is exported as isotropic point lights no farther apart than this (metres):
    /// lightning::append_point_sources keeps the total intensity exactly.
    double light_spacing = 0.0;
    /// The channel the frame draws (its core, seen by the camera): the lit stretches at t, and
    /// the radius they are drawn with (core radiance = intensity / (2 radius)). Empty when the
    /// frame draws no channel.
    std::span<const lightning::LitSegment> drawn_channel;
    double channel_radius = 0.0;
    /// The scene's density before its sub-voxel detail (scene::make_undetailed_density), when it
    /// declares detail: the export then samples the billows the march draws from it
    /// (cloud::detailed_on_finer_grid), or writes it as it is where the frame draws no detail.
    /// Null: the view's density grid (with detail, its voxel means).
    const core::Grid3<float>* undetailed = nullptr;
};

/// The most voxels the exported density may have when the billows are sampled on a finer grid
/// (cloud::detail_refinement): ~190 MB of floats while it is written. The default storm with
/// detail (144 x 144 x 80 voxels of 125 m, billows down to 37.5 m) gets 3x finer voxels (41.7 m).
inline constexpr std::uint64_t kMaxExportVoxels = 48'000'000;

/// Writes DIR/density.vdb (grid "density", rho; sigma_t = extinction * rho: the density the march
/// draws, with the billows on a finer grid when the frame draws them) and DIR/frame.json
/// (format "fulgur-blender-frame" version 1: camera, image size, medium, flash colour, the lit
/// channel as point lights, the drawn channel as segments, sun or moon, sky, ground), as `view`
/// renders with `options` (the
/// sun and sky only where they light the cloud in the frame, the sky and ground only where they
/// are drawn). `lit` is the frame's lit channel. Creates DIR; refuses a DIR that is a file.
void write_blender_export(const std::filesystem::path& dir, const view::StormView& view,
                          const view::ViewOptions& options, std::span<const lightning::LitSegment> lit,
                          const BlenderExport& e);

}  // namespace fulgur::app
