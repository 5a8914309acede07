// The demo's window shell: GLFW window + Dear ImGui set-up and teardown, frame timing and
// the frame rate over the last second, the orbit camera input, key edges (Space, C, H, P, Esc)
// and screenshots (P, or --screenshot-after N).
#pragma once

#include "platform/platform.h"

#include <cmath>
#include <deque>
#include <memory>
#include <string>

struct GLFWwindow;

namespace fulgur::app {

/// Orbit camera from the mouse: left-drag turns (azimuth; elevation clamped to -89..89
/// degrees, as a scene's camera), the wheel scales the distance (metres) within
/// [dist_min, dist_max]. ImGui keeps the mouse while it is over the panel.
struct Orbit {
    double az = 0, el = 0, dist = 1, dist_min = 0.1, dist_max = 10;
    /// Turns the azimuth by `deg`, kept in [-180, 180]: the printed camera stays one a scene
    /// takes (azimuth in [-360, 360]) however many turns the mouse or the turntable made.
    void turn(double deg) { az = std::remainder(az + deg, 360.0); }
};

class DemoShell {
public:
    /// Opens the window and ImGui. screenshot_after > 0: write a screenshot after that many
    /// frames and close.
    DemoShell(int width, int height, const std::string& title, int screenshot_after);
    ~DemoShell();
    DemoShell(const DemoShell&) = delete;
    DemoShell& operator=(const DemoShell&) = delete;

    /// Polls events, updates timing, the orbit and key edges, and starts the ImGui frame.
    /// False when the window should close.
    bool begin_frame(Orbit& orbit);
    /// Draws ImGui over the rendered frame, writes a screenshot when asked, presents. True when
    /// it wrote a screenshot.
    bool end_frame();

    platform::Context& context() noexcept { return *ctx_; }
    int width() const { return ctx_->width(); }
    int height() const { return ctx_->height(); }
    double dt() const noexcept { return dt_; }  ///< seconds since the previous frame
    /// Frames a second over the last second's frames (at least the last frame): the first
    /// frames, which compile shaders and upload the volume, drop out of it within a second.
    double fps() const noexcept { return fps_; }
    bool strike_pressed() const noexcept { return strike_; }  ///< Space went down this frame
    bool camera_pressed() const noexcept { return camera_; }  ///< C went down this frame
    /// Whether the ImGui windows are drawn: H toggles them (the storm alone on screen and in
    /// screenshots); --hide-panels starts without them.
    bool panels_shown() const noexcept { return panels_; }
    void show_panels(bool shown) noexcept { panels_ = shown; }
    void request_screenshot() noexcept { screenshot_ = true; }
    /// While held, --screenshot-after waits (e.g. for a reference solve still running).
    void hold_screenshot(bool hold) noexcept { hold_ = hold; }
    /// Moves a --screenshot-after screenshot due at the end of this frame to the next one.
    void delay_screenshot() noexcept {
        if (screenshot_after_ > 0 && frames_ + 1 >= screenshot_after_) screenshot_after_ = frames_ + 2;
    }
    int frames() const noexcept { return frames_; }

private:
    std::unique_ptr<platform::Context> ctx_;
    GLFWwindow* win_ = nullptr;
    int screenshot_after_ = 0, frames_ = 0, shots_ = 0;
    double dt_ = 0, fps_ = 0, mx_ = 0, my_ = 0;
    std::deque<double> recent_;  // the durations of the frames fps() counts (seconds)
    double recent_sum_ = 0;
    bool strike_ = false, camera_ = false, screenshot_ = false, space_down_ = false, p_down_ = false, c_down_ = false,
         h_down_ = false, hold_ = false, auto_shot_ = false, panels_ = true;
    double last_ = 0;
};

}  // namespace fulgur::app
