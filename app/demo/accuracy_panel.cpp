#include "demo/accuracy_panel.h"

#include "core/core.h"

#include <imgui.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>

namespace fulgur::app {

namespace {

// ImGui::Combo's item list: the run-time presets' names (NUL-terminated views into literals).
const std::array<const char*, scene::kInteractiveQualityPresets.size()> kPresets = [] {
    std::array<const char*, scene::kInteractiveQualityPresets.size()> names{};
    for (std::size_t i = 0; i < names.size(); ++i) names[i] = scene::kInteractiveQualityPresets[i].data();
    return names;
}();

double wall_seconds() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

AccuracyPanel::AccuracyPanel(view::StormView& view) : view_(view) {
    if (!view.has_lightning()) return;  // nothing to choose: no flash is lit
    const std::string_view current = scene::to_string(view.pipeline().quality().preset);
    for (std::size_t i = 0; i < kPresets.size(); ++i)
        if (current == kPresets[i]) preset_ = int(i);
}

AccuracyPanel::~AccuracyPanel() {
    if (pending_.valid()) pending_.wait();
}

const transport::SourceField* AccuracyPanel::shown_field() const noexcept {
    return reference_ && show_ ? &reference_->field : nullptr;
}

void AccuracyPanel::reset() {
    reference_.reset();  // a running solve finishes and is dropped when collected
    requested_ = -1;
}

void AccuracyPanel::update(double t, const view::ViewOptions& options) {
    if (!view_.has_lightning()) return;
    if (pending_.valid() && pending_.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
        Reference r = pending_.get();
        std::fprintf(stderr, "fulgur: %s %.2f s, frame %.3f ms, S off by %.1f%%\n", r.truth ? "truth" : "direct solve",
                     r.seconds, r.frame_ms, 100.0 * r.error);
        if (r.components.single == options.components.single && r.components.multiple == options.components.multiple)
            reference_ = std::move(r);
    }
    if (reference_ && (reference_->components.single != options.components.single ||
                       reference_->components.multiple != options.components.multiple))
        reset();  // the reference was solved for other components
    if (kPresets[std::size_t(preset_)] != scene::to_string(view_.pipeline().quality().preset)) {
        // Another preset: the pipeline is rebuilt (the bake is shared); the strike schedule
        // is the scene's, as at start.
        view_.set_quality(scene::quality_preset(kPresets[std::size_t(preset_)]));
        reset();
    }
    if (requested_ < 0 || pending_.valid()) return;
    const bool truth = requested_ == 1;
    // The frame as shown, all directions, built here (the pipeline is not thread-safe); the
    // worker gets copies and const references that nothing modifies while the view lives.
    runtime::ReconstructOptions ro;
    ro.components = options.components;
    std::vector<double> ms;
    const runtime::Frame* f = nullptr;
    for (int k = 0; k < 3; ++k) {
        f = &view_.pipeline().build(t, {}, ro);
        ms.push_back(f->times.total());
    }
    if (!f->lit) {
        std::fprintf(stderr, "fulgur: no flash at t = %.4f s: nothing to compare\n", t);
        requested_ = -1;
        return;
    }
    // The preset's own frame, not its fallback: wait (frame by frame, the window live) until
    // the worker has solved every strike that lights it.
    if (f->strikes_fallback > 0) return;
    requested_ = -1;
    std::sort(ms.begin(), ms.end());
    std::vector<float> shown;
    for (const std::vector<float>& v : f->radiance.values) shown.insert(shown.end(), v.begin(), v.end());
    const solve::Media& media = view_.media();
    std::fprintf(stderr, "fulgur: solving the frame at t = %.4f s against the %s on a worker thread...\n", t,
                 truth ? "truth" : "direct solve");
    started_ = wall_seconds();
    pending_ = std::async(std::launch::async, [scene = view_.scene(), &density = view_.density(), &media,
                                               segments = f->segments, sources = f->sources, shown = std::move(shown),
                                               frame_ms = ms[1], truth, components = options.components] {
        // One core for the solve, the other for the window.
        const core::ScopedThreadCount share(std::max(1, core::thread_count() - 1));
        Reference r;
        r.truth = truth;
        r.frame_ms = frame_ms;
        r.components = components;
        core::Stopwatch sw;
        if (truth) {
            const runtime::Truth tr = runtime::truth(scene, density, segments);
            r.field = tr.sum(components);
            r.noise = tr.noise.total;
        } else {
            r.field = runtime::direct_solve(scene, media, sources, components);
        }
        r.seconds = sw.seconds();
        core::RelativeL2 e;
        const std::vector<float>& rho = media.lighting.density.data;
        for (std::size_t i = 0; i < shown.size(); ++i)
            if (rho[i % rho.size()] > 0.0f) e.add(shown[i], r.field.data[i]);
        r.error = e.value();
        return r;
    });
}

void AccuracyPanel::draw(const view::FrameReport& rep) {
    if (!view_.has_lightning()) {
        ImGui::TextUnformatted("Quality (the scene has no lightning)");
        return;
    }
    ImGui::TextUnformatted("Quality");
    ImGui::Combo("preset", &preset_, kPresets.data(), int(kPresets.size()));
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "paper: the bases (Dobashi 2007)\n"
            "hybrid: the bases' multiple scattering + each strike's exact single scattering\n"
            "per_strike: each strike solved once on a worker thread (single + lattice)\n"
            "per_strike_mc: each strike by Monte Carlo on a worker thread (single + multiple)\n"
            "instant: the same Monte Carlo from the moment a strike is known, blended in as it converges\n"
            "(\"Strike now\" strikes are lit this way under every preset that solves ahead)\n"
            "docs/presets.md has the error against the truth and the cost of each");
    ImGui::Text("frame %.2f ms (strike light %.2f ms)", rep.stages.total(), rep.stages.strike_light);
    if (const runtime::StrikeSolver* solver = view_.pipeline().strike_solver()) {
        const std::vector<double> lat = solver->latencies();
        const runtime::Frame* f = view_.last_frame();
        ImGui::Text("strike solves: %zu, last %.2f s", lat.size(), lat.empty() ? 0.0 : lat.back());
        if (f && f->lit)
            ImGui::Text("this frame: %zu solved, %zu from the bases", f->strikes_solved, f->strikes_fallback);
    }
    if (view_.pipeline().instant_strikes()) {
        const runtime::Frame* f = view_.last_frame();
        if (f && f->lit)
            ImGui::Text("instant: own estimate's share %.0f%% (the rest from the bases)", 100.0 * f->instant_weight);
    }
    if (requested_ >= 0) {
        ImGui::TextUnformatted("waiting for the strike's own solve...");
    } else if (pending_.valid()) {
        ImGui::Text("solving the reference... %.0f s", wall_seconds() - started_);
    } else if (!reference_) {
        const runtime::Frame* f = view_.last_frame();
        ImGui::BeginDisabled(!(f && f->lit));
        if (ImGui::Button("Error against the truth")) request(true);
        ImGui::SameLine();
        if (ImGui::Button("against the direct solve")) request(false);
        ImGui::EndDisabled();
        if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
            ImGui::SetTooltip(
                "solves this frame on a worker thread (the window stays live, the storm time holds):\n"
                "the truth is Monte Carlo of the lit channel through the full density (~10-60 s);\n"
                "the direct solve is the scene's own solvers on the frame's sources, no bases (seconds)");
    } else {
        const Reference& r = *reference_;
        ImGui::Text("%s %.1f s; this frame %.2f ms", r.truth ? "truth" : "direct solve", r.seconds, r.frame_ms);
        ImGui::Text("S off by %.1f%% (rel. L2, cloud voxels)", 100.0 * r.error);
        if (r.truth) ImGui::Text("(truth's own noise %.1f%%)", 100.0 * r.noise);
        ImGui::Checkbox(r.truth ? "show the truth" : "show the direct solve", &show_);
        ImGui::SameLine();
        if (ImGui::Button("Release")) reset();
    }
}

}  // namespace fulgur::app
