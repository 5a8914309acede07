#include "demo/time_of_day.h"

#include <imgui.h>

#include <algorithm>
#include <cstdio>
#include <string>

namespace fulgur::app {

TimeOfDay::TimeOfDay(view::StormView& view, std::optional<double> start_hour)
    : view_(view), course_(sky::sun_course(*view.scene().sun)), shown_(course_.scene_hour) {
    resolver_ =
        std::make_unique<sky::SunResolver>(view.scene(), view.density(), view.static_media(), view.plan().settings, 1);
    hour_ = float(shown_);
    if (start_hour) {
        hour_ = float(std::clamp(*start_hour, course_.first_hour, course_.last_hour));
        request();
    }
}

void TimeOfDay::update() {
    std::optional<sky::SunSolve> r = resolver_->take();
    if (!r) return;
    // The request it answers (the ones before it were skipped); later ones are still coming.
    for (std::size_t i = requests_.size(); i-- > 0;)
        if (requests_[i].second == r->direction) {
            shown_ = requests_[i].first;
            requests_.erase(requests_.begin(), requests_.begin() + std::ptrdiff_t(i) + 1);
            break;
        }
    last_seconds_ = r->seconds;
    preview_ = r->preview;
    double el = 0.0, az = 0.0;
    course_.angles(shown_, el, az);
    std::printf("time of day: %.2f h (elevation %.1f deg, azimuth %.0f deg), %s in %.0f ms\n", shown_, el, az,
                preview_ ? "preview solved" : "solved", 1e3 * last_seconds_);
    view_.set_sun_solve(std::move(*r));
    view_.set_sun(course_.at(shown_));
}

void TimeOfDay::panel() {
    const std::string& name = view_.scene().sun->name;
    ImGui::Text("Time of day (the %s)", name.empty() ? "sun" : name.c_str());
    if (ImGui::SliderFloat("solar time (h)", &hour_, float(course_.first_hour), float(course_.last_hour), "%.2f"))
        request();
    double el = 0.0, az = 0.0;
    course_.angles(shown_, el, az);
    ImGui::Text("shown: %.2f h, elevation %.1f deg, azimuth %.0f deg", shown_, el, az);
    if (busy() && preview_)
        ImGui::Text("preview shown (%.0f ms); refining: order 2 by Monte Carlo...", 1e3 * last_seconds_);
    else if (busy())
        ImGui::TextUnformatted("solving the new direction (the old light stays shown)...");
    else if (last_seconds_ > 0.0)
        ImGui::Text("last re-solve %.0f ms", 1e3 * last_seconds_);
}

void TimeOfDay::request() {
    const glm::dvec3 d = course_.at(double(hour_)).direction;
    requests_.emplace_back(double(hour_), d);
    resolver_->request(d);
}

}  // namespace fulgur::app
