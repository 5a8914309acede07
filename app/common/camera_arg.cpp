#include "camera_arg.h"

#include "core/core.h"

#include <string>

namespace fulgur::app {

CLI::Option* add_camera_option(CLI::App& app, std::optional<scene::CameraSpec>& target, const char* tool) {
    return app
        .add_option_function<std::string>(
            "--camera",
            [&target, tool](const std::string& s) {
                try {
                    target = scene::camera_argument(s, "--camera");
                } catch (const core::Error& e) {
                    throw core::Error(tool, e.what());
                }
            },
            "the view: a scene's \"camera\" object as JSON text ('{\"orbit\": {\"azimuth\": -60, \"elevation\": "
            "10}}') or a file holding it (default: the scene's camera)")
        ->type_name("JSON|FILE");
}

}  // namespace fulgur::app
