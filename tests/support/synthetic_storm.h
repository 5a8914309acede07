// The synthetic storm: plausible renderer inputs (a procedural cloud, a bolt and a lighting
// model standing in for the bake and the run time) for the renderer's tests, its golden and
// documentation images and `fulgur-bench render`, so the renderer can be exercised without
// a bake. Test and benchmark support, not engine code. Coordinates follow
// cloud::cumulonimbus_geometry: z up, ground at z = 0, grid centred on x = y = 0.
#pragma once

#include "core/core.h"
#include "render/render.h"

#include <cstdint>
#include <vector>

namespace fulgur::synthetic {

/// A procedural cumulonimbus: a base layer, a tower of convective cells and an anvil built
/// from smooth blobs, eroded by fractal value noise. Deterministic per seed.
core::Grid3<float> cumulus(const core::Int3& dims = {128, 128, 96}, double voxel_size = 100.0, std::uint64_t seed = 1);

/// A lighting grid over `density`: the density grid box-filtered by `downsample` per axis.
core::GridGeometry lighting_geometry(const core::GridGeometry& density, int downsample);

/// S for a point flash of intensity `intensity` (W/sr) at `light`, on the lighting grid,
/// for the `direction_count` output directions (layout of transport::SourceField::data):
/// the exact single-scattering term albedo * p_HG(s . w) * I * T / (r^2 + r0^2) (T by ray
/// marching the density) plus a smooth isotropic diffusion-like term
/// albedo * I * T_ms exp(-r / l) / (4 pi (r l + r0^2)) standing in for multiple scattering.
std::vector<float> point_flash_source(const core::Grid3<float>& density, double extinction,
                                      const core::GridGeometry& lighting, int direction_count, const glm::dvec3& light,
                                      double intensity, double albedo = 0.99, double g = 0.6);

/// S for a whole bolt: point flashes every `spacing` metres along its segments, each of
/// intensity (segment intensity x length share), summed (S is linear in the sources).
std::vector<float> bolt_source(const core::Grid3<float>& density, double extinction, const core::GridGeometry& lighting,
                               int direction_count, const render::LitChannel& bolt, double spacing = 400.0,
                               double albedo = 0.99, double g = 0.6);

/// A branching cloud-to-ground bolt (Reed-Wyvill-style random walk, deterministic per seed)
/// from `start` to the ground plane z = 0; `intensity` is the main channel's W/sr per metre.
render::LitChannel bolt(std::uint64_t seed, const glm::dvec3& start, double intensity, double radius = 2.0);

/// The synthetic storm used by the renderer's golden test, benchmark and documentation
/// image: a cumulonimbus (seed 7), a cloud-to-ground bolt from 6.8 km (seed 3) whose channel
/// lights the cloud (bolt_source, 26 directions, lighting grid = density / 4), a camera
/// 13.5 km away looking slightly up, and settings for a long-exposure night look.
struct Storm {
    core::Grid3<float> density;
    double extinction = 0.004;
    core::GridGeometry lighting;
    int directions = 26;
    std::vector<float> source;  ///< transport::SourceField layout
    render::LitChannel bolt;
    render::Camera camera;
    render::Settings settings;
};

/// dims/voxel: {128,128,96} x 100 m (full) or e.g. {64,64,48} x 200 m (fast).
Storm storm(const core::Int3& dims = {128, 128, 96}, double voxel_size = 100.0);

/// An upload of the directions of `storm.source` that `renderer` says the camera needs.
render::SourceUpload needed_upload(const render::Renderer& renderer, const Storm& storm);

/// What the temporal history's tests and benchmark orbit about: the storm's middle, 70% of the
/// way up.
glm::dvec3 orbit_target(const Storm& storm);

/// A camera on that orbit at the distance of the storm's own camera from its target.
render::Camera orbit_camera(const Storm& storm, double azimuth_deg, double elevation_deg, double vertical_fov_deg);

}  // namespace fulgur::synthetic
