// fulgur::view — a frame's linear radiance (W m^-2 sr^-1) before exposure and tone map, whole
// and in passes: what an EXR carries to a compositor, and what an outside renderer's image is
// compared with.
#pragma once

#include "view/view.h"

#include <string>
#include <vector>

namespace fulgur::view {

/// One term of the frame as an image: RGB float, rows top to bottom.
struct LinearPass {
    std::string name;
    std::vector<float> rgb;
};

/// The names of the passes, in the order render_linear gives them. Their sum is the frame:
///   lightning   the cloud's in-scattered light of the flash (S)
///   static      the cloud's light of the sun or moon and the sky (S, and the sun's single
///               scattering at full resolution)
///   glow        the air's scattering around the channel, through the cloud in front of it
///   channel     the channel's core
///   background  the sky, the stars and the lit ground, times the cloud's transmittance
inline constexpr const char* kLinearPasses[] = {"lightning", "static", "glow", "channel", "background"};

struct LinearFrame {
    int width = 0, height = 0;
    std::vector<float> radiance;     ///< the whole frame, RGB
    std::vector<LinearPass> passes;  ///< kLinearPasses (when asked for)
    /// The cloud's transmittance along each pixel's ray, one value per pixel (with the passes).
    std::vector<float> transmittance;
};

/// Renders the frame at t like StormView::render and reads its radiance; the bound framebuffer
/// is drawn into (with the passes it holds the last of them afterwards). The eye's glare is left
/// out: it is a display effect, not radiance. With `passes`
/// each term is re-composited from the same frame (same density, S, channel and ray-march
/// jitter) with only that term on, so the passes sum to `radiance` up to float rounding, and
/// the transmittance is the frame seen against a uniform unit sky with no light.
LinearFrame render_linear(StormView& view, const render::Camera& camera, double t, int width, int height,
                          const ViewOptions& options, const transport::SourceField* source = nullptr,
                          bool passes = false, const transport::SourceField* rain_source = nullptr);

}  // namespace fulgur::view
