#include "demo/plots.h"

#include <imgui.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace fulgur::app {

namespace {

// Median of a copy (the overlay's steady figure: single frames stall on a shared machine).
float median(std::vector<float> v) {
    if (v.empty()) return 0.0f;
    const auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return *mid;
}

// Marks x in [0, 1] of the last drawn item with a vertical line.
void mark_last_item(float x, ImU32 colour) {
    const ImVec2 lo = ImGui::GetItemRectMin(), hi = ImGui::GetItemRectMax();
    const float px = lo.x + std::clamp(x, 0.0f, 1.0f) * (hi.x - lo.x);
    ImGui::GetWindowDrawList()->AddLine({px, lo.y}, {px, hi.y}, colour, 1.5f);
}

}  // namespace

void FrameTimePlots::add(const view::FrameReport& rep) {
    const float reconstruction = float(rep.stages.total());
    const float upload = float(rep.gpu.wall.upload), march = float(rep.gpu.wall.march);
    const float values[kStages] = {float(rep.wall_ms), reconstruction, upload, march,
                                   std::max(0.0f, float(rep.gpu.wall.total) - upload - march)};
    for (int s = 0; s < kStages; ++s) ms_[std::size_t(s)][next_] = values[s];
    next_ = (next_ + 1) % kFrames;
    count_ = std::min(count_ + 1, kFrames);
}

void FrameTimePlots::draw() const {
    static constexpr const char* kNames[kStages] = {"frame", "reconstruct (CPU)", "upload S", "ray march",
                                                    "other passes"};
    if (count_ == 0) return;
    const float width = ImGui::GetContentRegionAvail().x;
    for (int s = 0; s < kStages; ++s) {
        const auto& ring = ms_[std::size_t(s)];
        // Oldest first: the ring from next_ when full, from 0 while filling.
        std::vector<float> v(count_);
        const std::size_t first = count_ == kFrames ? next_ : 0;
        for (std::size_t i = 0; i < count_; ++i) v[i] = ring[(first + i) % kFrames];
        const float latest = v.back(), med = median(v);
        const float top = std::max(1e-3f, *std::max_element(v.begin(), v.end()));
        char overlay[96];
        std::snprintf(overlay, sizeof overlay, "%s %.2f ms (median %.2f, max %.2f)", kNames[s], latest, med, top);
        ImGui::PlotLines(("##stage" + std::to_string(s)).c_str(), v.data(), int(v.size()), 0, overlay, 0.0f,
                         1.05f * top, {width, s == Frame ? 46.0f : 32.0f});
    }
}

void FlashPlot::draw(lightning::Storm& storm, double t) {
    const std::span<const std::size_t> active = storm.active(t);
    if (!active.empty() && (!strike_ || *strike_ != active.back())) {
        // A new strike: its flash sampled over its whole duration (pure functions of the
        // strike's profile and bolt: no effect on the storm's schedule).
        strike_ = active.back();
        const lightning::Strike& s = storm.strike(*strike_);
        const lightning::Bolt& bolt = storm.bolt(*strike_);
        start_ = s.time;
        duration_ = s.profile.duration;
        std::vector<double> intensity(kSamples, 0.0);
        std::vector<lightning::LitSegment> lit;
        for (int i = 0; i < kSamples; ++i) {
            const double tau = duration_ * (i + 0.5) / kSamples;
            lit.clear();
            lightning::lit_segments(bolt, lightning::flash_state(s.profile, storm.params().timing, tau), lit);
            for (const lightning::LitSegment& seg : lit)
                intensity[std::size_t(i)] += seg.intensity * glm::length(seg.b - seg.a);
        }
        peak_ = *std::max_element(intensity.begin(), intensity.end());
        // Four decades below the peak: the leaders and the restrikes' tails stay visible.
        const double floor = peak_ > 0.0 ? peak_ * 1e-4 : 1.0;
        log_intensity_.assign(kSamples, 0.0f);
        for (int i = 0; i < kSamples; ++i)
            log_intensity_[std::size_t(i)] = float(std::log10(std::max(intensity[std::size_t(i)], floor) / floor));
    }
    if (!strike_ || log_intensity_.empty()) {
        ImGui::TextDisabled("flash: no strike yet");
        return;
    }
    char overlay[96];
    std::snprintf(overlay, sizeof overlay, "flash, %.0f ms, peak %.2g W/sr (log, 4 decades)", 1e3 * duration_, peak_);
    ImGui::PlotLines("##flash", log_intensity_.data(), int(log_intensity_.size()), 0, overlay, 0.0f, 4.3f,
                     {ImGui::GetContentRegionAvail().x, 56.0f});
    const float x = duration_ > 0.0 ? float((t - start_) / duration_) : 0.0f;
    if (x >= 0.0f && x <= 1.0f) mark_last_item(x, IM_COL32(255, 200, 60, 255));
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "the latest strike's channel intensity (sum of intensity x length over its lit\n"
            "stretches) from the stepped leader to the end of its last stroke; the line is now");
}

}  // namespace fulgur::app
