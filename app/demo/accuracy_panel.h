// The demo panel's "Quality" section: the preset in use (selectable), its frame time and
// per-strike solve latency, and on demand the error of the frame against the direct solve or
// the truth, solved on a worker thread while the window stays live (the storm time holds
// until the user releases it); and the static light's (sun or moon, sky) error against its
// truth, solved the same way, with the truth shown in its place on request.
#pragma once

#include "view/view.h"

#include <future>
#include <optional>
#include <string>

namespace fulgur::app {

class AccuracyPanel {
public:
    explicit AccuracyPanel(view::StormView& view);
    ~AccuracyPanel();

    /// Draws the section into the current ImGui window.
    void draw(const view::FrameReport& rep);
    /// Once per frame, before rendering: applies a preset change, starts a requested reference
    /// solve (of the frame at t), collects a finished one.
    void update(double t, const view::ViewOptions& options);
    /// A reference solve is running or shown: the storm time must hold.
    bool holds_time() const noexcept { return requested_ >= 0 || pending_.valid() || reference_.has_value(); }
    /// A reference solve (of the frame or of the static light) is asked for or running.
    bool busy() const noexcept {
        return requested_ >= 0 || pending_.valid() || static_requested_ || static_pending_.valid();
    }
    /// The field to light the cloud with instead of the frame's (the reference, when shown).
    const transport::SourceField* shown_field() const noexcept;
    /// With it, the light at the rain (the truth's in a scene with rain, else empty: the channel
    /// alone lights the rain; null without it).
    const transport::SourceField* shown_rain() const noexcept;
    /// Drops the reference (a new strike, new lightning, other components).
    void reset();
    /// Asks for a reference solve of the next frame: the truth, or the direct solve.
    void request(bool truth) { requested_ = truth ? 1 : 0; }
    /// Asks for the static light's truth (scenes with a sun or a sky).
    void request_static() { static_requested_ = true; }

private:
    struct Reference {
        transport::SourceField field, rain;
        bool truth = false;
        double seconds = 0.0, frame_ms = 0.0, error = 0.0, noise = 0.0;
        runtime::Components components;
    };
    view::StormView& view_;
    int preset_ = 0;      // index into the preset names
    int requested_ = -1;  // -1 none, 0 direct solve, 1 truth
    std::future<Reference> pending_;
    std::optional<Reference> reference_;
    bool show_ = true;
    runtime::Components components_;  // those the reference was solved for
    double started_ = 0.0;            // wall seconds when the pending solve started

    // The static light against its truth.
    struct StaticReference {
        sky::StaticLight truth, solved;  // the truth, and the solves it replaces while shown
        std::vector<transport::MonteCarloResult::Noise> noise;
        double seconds = 0.0, single = 0.0, multiple = 0.0, total = 0.0;
    };
    void update_static(const view::ViewOptions& options);
    void draw_lightning(const view::FrameReport& rep);  // the preset, the strike solves, the reference
    void draw_static();
    void release_static();  // shows the solves again and drops the truth
    bool static_requested_ = false;
    std::future<StaticReference> static_pending_;
    std::optional<StaticReference> static_;
    bool static_shown_ = false;  // the truth is what the view shows
    bool static_show_ = true;    // the checkbox
    double static_started_ = 0.0;
};

}  // namespace fulgur::app
