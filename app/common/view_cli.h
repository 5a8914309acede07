// The command-line face of fulgur::view shared by `fulgur` and `fulgur-shot`: baking with a
// progress bar on stderr, and the JSON line of a frame's stage times.
#pragma once

#include "view/view.h"

#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>

namespace fulgur::app {

/// view::ensure_baked, saying "baking FILE (why)" and drawing a progress bar on stderr.
std::filesystem::path ensure_baked(const scene::Scene& s, const core::Grid3<float>& density,
                                   const std::optional<std::filesystem::path>& explicit_fgb);

/// The scene's plan (sky::plan_scene, no estimates), its reasons printed to `out` (one
/// "plan: ..." line each).
sky::ScenePlan plan_and_print(const scene::Scene& s, const core::Grid3<float>& density, std::FILE* out);

/// view::bases_for with ensure_baked's messages: the .fgb when the plan bakes, else none.
std::optional<std::filesystem::path> bases_for(const sky::ScenePlan& plan, const scene::Scene& s,
                                               const core::Grid3<float>& density,
                                               const std::optional<std::filesystem::path>& explicit_fgb);

/// The scene's density as the apps load it: `density` is scene::make_density's (what the
/// solvers integrate); for a scene with sub-voxel detail, `undetailed` is the cloud before its
/// detail, which the renderer erodes per sample (the cloud generated or loaded once for both).
struct SceneDensity {
    core::Grid3<float> density;
    std::optional<core::Grid3<float>> undetailed;
};
SceneDensity load_density(const scene::Scene& s);

/// What a view of the scene is set up with: its plan, the static light cached beside the
/// scene, what is solved or read printed to `out`, and `d`'s undetailed density when given.
view::StaticSetup static_setup(const sky::ScenePlan& plan, std::FILE* out, const SceneDensity* d = nullptr);

/// The JSON line fulgur-shot (and the demo's headless frames) print (stage times in ms).
std::string timings_json(const view::FrameReport& r, int width, int height, const char* name = "fulgur-shot");

}  // namespace fulgur::app
