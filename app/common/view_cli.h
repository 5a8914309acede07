// The command-line face of fulgur::view shared by `fulgur` and `fulgur-shot`: baking with a
// progress bar on stderr, and the JSON line of a frame's stage times.
#pragma once

#include "view/view.h"

#include <filesystem>
#include <optional>
#include <string>

namespace fulgur::app {

/// view::ensure_baked, saying "baking FILE (why)" and drawing a progress bar on stderr.
std::filesystem::path ensure_baked(const scene::Scene& s, const core::Grid3<float>& density,
                                   const std::optional<std::filesystem::path>& explicit_fgb);

/// The JSON line fulgur-shot (and the demo's headless frames) print (stage times in ms).
std::string timings_json(const view::FrameReport& r, int width, int height, const char* name = "fulgur-shot");

}  // namespace fulgur::app
