// The demo panel's "Time of day" section: the scene's sun (or moon) moved along its course
// (sky::SunCourse). A new direction is solved on a worker thread (sky::SunResolver, one core:
// the other keeps rendering) while the view keeps showing the field of the last solve;
// irradiance and colour follow the solve that arrives, so what is shown is always one
// consistent sun.
#pragma once

#include "view/view.h"

#include <glm/vec3.hpp>

#include <memory>
#include <optional>
#include <utility>
#include <vector>

namespace fulgur::app {

class TimeOfDay {
public:
    /// Keeps references into `view` (scene, density, media): declare it after the view. The
    /// scene must have a sun. start_hour: solar time to solve for at once (clamped to the course).
    TimeOfDay(view::StormView& view, std::optional<double> start_hour);
    /// Takes a finished solve (the newest) and shows it.
    void update();
    /// A solve is running.
    bool busy() const { return resolver_->busy(); }
    /// Draws the section into the current ImGui window: the slider, where the sun stands, the
    /// re-solve's state.
    void panel();

private:
    void request();
    view::StormView& view_;
    sky::SunCourse course_;
    std::unique_ptr<sky::SunResolver> resolver_;
    std::vector<std::pair<double, glm::dvec3>> requests_;  // not yet shown: hour and direction
    float hour_ = 12.0f;
    double shown_ = 12.0, last_seconds_ = 0.0;
    bool preview_ = false;  // the shown field is a SunResolver preview; its refined solve follows
};

}  // namespace fulgur::app
