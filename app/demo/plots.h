// The demo panel's charts (Dear ImGui's own plot widgets): the frame time per stage over the
// last seconds, and the flash of the latest strike over its whole duration with the storm's
// current time marked, so the cost and the flash are seen rather than read.
#pragma once

#include "lightning/lightning.h"
#include "view/view.h"

#include <array>
#include <cstddef>
#include <optional>
#include <vector>

namespace fulgur::app {

/// Frame times per stage over the last kFrames frames.
class FrameTimePlots {
public:
    static constexpr std::size_t kFrames = 240;
    /// Records one frame's report.
    void add(const view::FrameReport& rep);
    /// Draws one plot line per stage (its latest and median figures in the overlay).
    void draw() const;

private:
    enum Stage { Frame, Reconstruction, Upload, March, GpuRest, kStages };
    std::array<std::array<float, kFrames>, kStages> ms_{};
    std::size_t next_ = 0, count_ = 0;
};

/// The latest strike's flash: its channel's total intensity (W/sr, sum over lit stretches of
/// intensity x length) from the leader's start to the end of its last stroke, log scale.
class FlashPlot {
public:
    /// Draws the flash of the strike active at storm time t (or the last one drawn), with t marked.
    void draw(lightning::Storm& storm, double t);

private:
    static constexpr int kSamples = 256;
    std::optional<std::size_t> strike_;  // the strike the curve belongs to
    double start_ = 0.0, duration_ = 0.0, peak_ = 0.0;
    std::vector<float> log_intensity_;
};

}  // namespace fulgur::app
