// The demo's control panel (the "Fulgur" ImGui window): lightning (seed, strikes, rate, time
// scale, bolt shape, the flash plot), light (components, bolt, ground, sun and sky, exposure,
// internal scale), time of day, quality and the frame-time plots. It holds what the user set
// and applies it to the view between frames.
#pragma once

#include <utility>

#include "demo/accuracy_panel.h"
#include "demo/plots.h"
#include "demo/shell.h"
#include "demo/time_of_day.h"
#include "view/view.h"

namespace fulgur::app {

class DemoPanel {
public:
    /// Keeps references to view, accuracy and time_of_day (null: the scene has no sun).
    /// seed: the first strike's seed; time_scale: storm seconds per wall second.
    DemoPanel(view::StormView& view, AccuracyPanel& accuracy, TimeOfDay* time_of_day, int seed, double time_scale);

    /// Draws the window for the frame at storm time t (rep: the previous frame's report),
    /// writing the light switches into opt. True when a strike was asked for (Space or the
    /// button).
    bool draw(const DemoShell& shell, double t, const view::FrameReport& rep, view::ViewOptions& opt);
    /// After drawing: a changed bolt shape or strike rate makes a new storm (bolts regenerate,
    /// same bake); a requested strike starts at t with the next seed.
    void apply(double t, bool strike);
    /// "Print camera" was pressed since the last call.
    bool take_camera_request() noexcept { return std::exchange(camera_request_, false); }
    /// Records a rendered frame in the frame-time plots.
    void add_frame(const view::FrameReport& rep) { frame_plots_.add(rep); }
    /// Storm seconds per wall second (the slider).
    double time_scale() const noexcept { return double(slow_); }
    /// The turntable: degrees of azimuth per wall second the camera turns by on its own (0: off).
    double turn_rate() const noexcept { return turning_ ? double(turn_deg_per_s_) : 0.0; }
    /// Starts turning at `deg_per_s` (--orbit); 0 leaves the turntable off at its default rate.
    void turn(double deg_per_s) noexcept {
        turning_ = deg_per_s != 0.0;
        if (turning_) turn_deg_per_s_ = float(deg_per_s);
    }

private:
    bool lightning_section(double t);
    void light_section(view::ViewOptions& opt, const view::FrameReport& rep, double dt);
    void frame_times(const view::FrameReport& rep);

    view::StormView& view_;
    AccuracyPanel& accuracy_;
    TimeOfDay* time_of_day_;
    bool has_lightning_, separate_;
    bool camera_request_ = false;
    float rate_;
    int seed_;
    bool autos_;
    float slow_;
    lightning::LightningParams lp_;
    bool shape_changed_ = false;
    bool turning_ = false;
    float turn_deg_per_s_ = 20.0f;
    FrameTimePlots frame_plots_;
    FlashPlot flash_plot_;
};

}  // namespace fulgur::app
