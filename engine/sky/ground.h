// fulgur::sky — the static light on the ground under the cloud: what the sun (or moon) and
// the sky give a ground plane besides the sun's direct beam (which the renderer shadows per
// pixel): the light the cloud scatters down, and the sky seen through the cloud.
#pragma once

#include "scene/scene.h"
#include "sky/sky.h"
#include "solve/solve.h"
#include "transport/ground_dome.h"
#include "transport/transport.h"

#include <optional>
#include <vector>

namespace fulgur::sky {

/// The cells the static light's ground is kept on: the scene's ground plane (the bolt's
/// ground height) under `lighting` and 20 km around it, cells of two lighting voxels, made
/// coarser when that would take more than 128 along a side, or more than ground_dome's work
/// bound allows at its default rays for a grid that large. None when the scene has no ground.
std::optional<transport::GroundTally> static_ground_cells(const scene::Scene& s, const core::GridGeometry& lighting);

/// The static light's ground per unit light, W/m^2 per cell (GroundTally order): `sun`, the
/// light the cloud scatters down of a unit irradiance; `zenith`, `horizon` (or `uniform`),
/// each end of the sky's gradient at unit radiance, the cloud's scattered light plus the sky
/// seen through the cloud. Empty where the light has no such part. The sun's direct beam is
/// not in it.
struct StaticGround {
    transport::GroundTally cells;
    std::vector<float> sun, zenith, horizon, uniform;
    double seconds = 0.0;
};
/// From the static light's S on `media`'s lighting grid by transport::ground_dome (the rays
/// also give the sky's transmittance; its error against the truth's tally: docs/sky.md).
StaticGround static_ground(const solve::Media& media, const StaticLight& light, const transport::GroundTally& cells,
                           const transport::DomeGroundOptions& options = {});

/// The ground's irradiance in colour, 3 floats per cell: sun x the sun's irradiance and colour
/// (when `use_sun`), the sky's parts x its colours (when `use_sky`). Empty when nothing is used.
std::vector<float> compose_ground(const StaticGround& g, const std::optional<scene::Sun>& sun,
                                  const std::optional<scene::SkyDome>& sky, bool use_sun, bool use_sky);

}  // namespace fulgur::sky
