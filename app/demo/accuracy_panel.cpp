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
    if (static_pending_.valid()) static_pending_.wait();
}

const transport::SourceField* AccuracyPanel::shown_field() const noexcept {
    return reference_ && show_ ? &reference_->field : nullptr;
}

const transport::SourceField* AccuracyPanel::shown_rain() const noexcept {
    return reference_ && show_ ? &reference_->rain : nullptr;
}

void AccuracyPanel::reset() {
    reference_.reset();  // a running solve finishes and is dropped when collected
    requested_ = -1;
}

void AccuracyPanel::update(double t, const view::ViewOptions& options) {
    update_static(options);
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
            r.rain = tr.rain_light(scene, components);
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

void AccuracyPanel::release_static() {
    // The sun may have moved meanwhile (time of day): its new solve stays, the sky's solve returns.
    if (static_shown_) {
        sky::StaticLight back = static_->solved;
        if (back.sun && view_.static_light().sun_direction != static_->truth.sun_direction) {
            back.sun = view_.static_light().sun;
            back.sun_direction = view_.static_light().sun_direction;
        }
        view_.set_static_light(std::move(back));
    }
    static_shown_ = false;
    static_.reset();
}

void AccuracyPanel::update_static(const view::ViewOptions& options) {
    if (static_pending_.valid() && static_pending_.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
        StaticReference r = static_pending_.get();
        std::fprintf(stderr, "fulgur: static light's truth %.1f s: S off by %.1f%% (single %.1f%%, multiple %.1f%%)\n",
                     r.seconds, 100.0 * r.total, 100.0 * r.single, 100.0 * r.multiple);
        // A sun that moved meanwhile makes the truth another direction's: dropped.
        if (!r.truth.sun || r.truth.sun_direction == view_.static_light().sun_direction) static_ = std::move(r);
    }
    if (static_ && static_->truth.sun && static_->truth.sun_direction != view_.static_light().sun_direction)
        release_static();  // the time of day moved the sun
    if (static_) {
        const bool want = static_show_;
        if (want != static_shown_) {
            view_.set_static_light(want ? static_->truth : static_->solved);
            static_shown_ = want;
        }
    }
    if (!static_requested_ || static_pending_.valid()) return;
    static_requested_ = false;
    const sky::ScenePlan& plan = view_.plan();
    if (!plan.sun && !plan.sky) return;
    // Copies for the worker (the view's static light changes with the time of day); the
    // static media are built here, on the thread that owns the view.
    const solve::Media& media = view_.static_media();
    std::fprintf(stderr, "fulgur: solving the static light's truth on a worker thread...\n");
    static_started_ = wall_seconds();
    static_pending_ = std::async(std::launch::async, [scene = view_.scene(), &density = view_.density(), &media, plan,
                                                      solved = view_.static_light(), sun = view_.shown_sun(), options] {
        const core::ScopedThreadCount share(std::max(1, core::thread_count() - 1));
        core::Stopwatch sw;
        StaticReference r;
        r.solved = solved;
        sky::TruthOptions to;
        to.paths = 2'000'000;
        r.truth = sky::truth_of(scene, density, plan, media, solved, transport::output_directions(plan.directions), to,
                                &r.noise);
        sky::ComposeOptions co;
        co.sun = options.sun;
        co.sky = options.sky;
        double* err[3] = {&r.single, &r.multiple, &r.total};
        for (int part = 0; part < 3; ++part) {
            co.single = part != 1;
            co.multiple = part != 0;
            *err[part] = sky::colour_error(sky::compose(solved, sun, scene.sky, co),
                                           sky::compose(r.truth, sun, scene.sky, co), media.lighting.density.data);
        }
        r.seconds = sw.seconds();
        return r;
    });
}

void AccuracyPanel::draw_static() {
    const sky::ScenePlan& plan = view_.plan();
    if (!plan.sun && !plan.sky) return;
    ImGui::Separator();
    ImGui::TextUnformatted("Static light (sun or moon, sky)");
    if (static_pending_.valid()) {
        ImGui::Text("solving its truth... %.0f s", wall_seconds() - static_started_);
    } else if (!static_) {
        if (ImGui::Button("Static light against its truth")) request_static();
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "Monte Carlo of the sun and of the whole sky dome through the full-resolution density\n"
                "(2M paths per light, on a worker thread: a minute or more); the error of the solves\n"
                "the renderer draws (docs/sky.md has the figures for every configuration)");
    } else {
        const StaticReference& r = *static_;
        double noise = 0.0;
        for (const auto& n : r.noise) noise = std::max(noise, n.total);
        ImGui::Text("truth %.1f s: S off by %.1f%% (single %.1f%%, multiple %.1f%%)", r.seconds, 100.0 * r.total,
                    100.0 * r.single, 100.0 * r.multiple);
        ImGui::Text("(truth's own noise %.1f%%)", 100.0 * noise);
        ImGui::Checkbox("show the static light's truth", &static_show_);
        ImGui::SameLine();
        if (ImGui::Button("Release##static")) release_static();
    }
}

void AccuracyPanel::draw(const view::FrameReport& rep) {
    if (view_.has_lightning())
        draw_lightning(rep);
    else
        ImGui::TextUnformatted("(the scene has no lightning)");
    draw_static();
}

void AccuracyPanel::draw_lightning(const view::FrameReport& rep) {
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
