// The --camera option fulgur-shot and fulgur share: a scene's "camera" object, as JSON text or
// a file holding it, validated as the scene's (scene::camera_argument).
#pragma once

#include "scene/scene.h"

#include <CLI/CLI.hpp>

#include <optional>

namespace fulgur::app {

/// Declares --camera JSON|FILE on `app`, writing into `target`; an invalid camera is a usage
/// error "<tool>: --camera...: <field>: <reason>".
CLI::Option* add_camera_option(CLI::App& app, std::optional<scene::CameraSpec>& target, const char* tool);

}  // namespace fulgur::app
