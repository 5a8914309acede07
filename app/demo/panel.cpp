#include "demo/panel.h"

#include <imgui.h>

#include <cfloat>
#include <cmath>

namespace fulgur::app {

namespace {

// The exposure controls: automatic (with eye adaptation: at once toward a flash, over
// seconds back to the night) and its compensation, or a manual exposure starting from the
// last automatic one.
void exposure_panel(render::Settings& st, const view::FrameReport& last, double dt) {
    const bool was_auto = st.auto_exposure;
    ImGui::Checkbox("automatic exposure", &st.auto_exposure);
    if (was_auto && !st.auto_exposure && last.gpu.exposure > 0.0) st.exposure = last.gpu.exposure;
    if (st.auto_exposure) {
        float ev = float(st.exposure_compensation);
        if (ImGui::SliderFloat("compensation (EV)", &ev, -4.0f, 4.0f)) st.exposure_compensation = double(ev);
        ImGui::Text("exposure %.3g (metered %.3g)", last.gpu.exposure, last.gpu.metered_exposure);
        st.previous_exposure = last.gpu.exposure;
        st.adaptation_seconds = dt;
    } else {
        float expo = float(std::log2(st.exposure));
        if (ImGui::SliderFloat("exposure (EV)", &expo, -20.0f, 16.0f)) st.exposure = std::exp2(double(expo));
    }
}

// The static light's run-time switches (the scene's effects must call for each).
void static_light_panel(view::ViewOptions& opt, const sky::ScenePlan& plan) {
    ImGui::BeginDisabled(!plan.sun);
    ImGui::Checkbox("sun / moon", &opt.sun);
    ImGui::SameLine();
    ImGui::Checkbox("silver lining (full resolution)", &opt.sun_full_resolution);
    ImGui::EndDisabled();
    ImGui::BeginDisabled(!plan.sky);
    ImGui::Checkbox("sky light", &opt.sky);
    ImGui::EndDisabled();
    // transport.static_light.directions "camera": one field toward the scene's camera, which
    // this view's camera leaves as soon as it moves.
    if (plan.settings.toward && (plan.sun || plan.sky)) {
        const glm::dvec3& c = *plan.settings.toward;
        ImGui::TextWrapped(
            "sun and sky light solved toward the scene's camera at (%.0f, %.0f, %.0f) m: "
            "exact from there only (a still shot's setting)",
            c.x, c.y, c.z);
    }
}

}  // namespace

DemoPanel::DemoPanel(view::StormView& view, AccuracyPanel& accuracy, TimeOfDay* time_of_day, int seed,
                     double time_scale)
    : view_(view),
      accuracy_(accuracy),
      time_of_day_(time_of_day),
      has_lightning_(view.has_lightning()),
      separate_(has_lightning_ ? view.bases().has_multiple() : view.scene().effects.multiple_scattering),
      rate_(float(view.scene().lightning.schedule.strike_rate)),
      seed_(seed),
      autos_(rate_ > 0),
      slow_(float(time_scale)),
      lp_(view.scene().lightning) {
    // The slider holds a float: compare against what it can represent, or the first frame
    // would see a "changed" rate and rebuild the storm (dropping the first strike).
    lp_.schedule.strike_rate = autos_ ? double(rate_) : 0.0;
}

bool DemoPanel::draw(const DemoShell& shell, double t, const view::FrameReport& rep, view::ViewOptions& opt) {
    bool strike = shell.strike_pressed();
    ImGui::SetNextWindowPos({10, 10}, ImGuiCond_FirstUseEver);
    // As high as its open sections, 380 pixels wide (sliders 11 font heights, their labels
    // beside them): a 1280x720 view keeps the storm in its left third in sight.
    ImGui::SetNextWindowSizeConstraints({380, 0}, {380, FLT_MAX});
    ImGui::Begin("Fulgur", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::PushItemWidth(11.0f * ImGui::GetFontSize());
    // The window's frames: the view, the panel and the swap, with the GPU's work (the view's
    // own wall time ends before llvmpipe's threads finish drawing; the plots give its stages).
    ImGui::Text("%.1f fps  (%.1f ms a frame)", shell.fps(), 1000.0 / shell.fps());
    if (ImGui::Button("Print camera (C)")) camera_request_ = true;
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "prints the view as a scene's \"camera\" (stdout and the clipboard): for the scene file, "
            "fulgur-shot --camera or fulgur --camera; drag to turn, wheel to move closer");
    ImGui::SameLine();
    ImGui::TextDisabled("H hides the panels");
    ImGui::Checkbox("turn", &turning_);
    ImGui::SameLine();
    ImGui::SliderFloat("deg/s", &turn_deg_per_s_, -90.0f, 90.0f, "%.0f");
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip("the camera orbits its target on its own (a turntable; negative: the other way)");
    // Sections the user opens: the lightning and the quality open at first (the time of day
    // instead of the lightning in a scene without lightning, whose sun is its main control);
    // the light's switches and the frame-time plots closed, so that the panel leaves most of a
    // 1280x720 view to the storm.
    const ImGuiTreeNodeFlags lightning_open = has_lightning_ ? ImGuiTreeNodeFlags_DefaultOpen : 0;
    if (ImGui::CollapsingHeader("Lightning", lightning_open) && lightning_section(t)) strike = true;
    if (ImGui::CollapsingHeader("Light")) light_section(opt, rep, shell.dt());
    if (time_of_day_ && ImGui::CollapsingHeader("Time of day", has_lightning_ ? 0 : ImGuiTreeNodeFlags_DefaultOpen))
        time_of_day_->panel();
    if (ImGui::CollapsingHeader("Quality and accuracy", ImGuiTreeNodeFlags_DefaultOpen)) accuracy_.draw(rep);
    if (ImGui::CollapsingHeader("Frame times")) frame_times(rep);
    ImGui::PopItemWidth();
    ImGui::End();
    return strike;
}

// The lightning section; true when "Strike now" was pressed.
bool DemoPanel::lightning_section(double t) {
    bool strike = false;
    ImGui::BeginDisabled(!has_lightning_);
    if (!has_lightning_) ImGui::TextUnformatted("(the scene has none)");
    ImGui::InputInt("seed", &seed_);
    if (ImGui::Button("Strike now")) strike = true;
    ImGui::Checkbox("automatic strikes", &autos_);
    ImGui::SliderFloat("rate (1/s)", &rate_, 0.01f, 2.0f);
    ImGui::SliderFloat("time scale", &slow_, 0.01f, 1.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip("storm seconds per wall second (slow motion: a flash decays in ~12 ms)");
    if (has_lightning_) flash_plot_.draw(view_.pipeline().storm(), t);
    lightning::BoltParams& b = lp_.bolt;
    int kind = int(b.kind);
    bool changed = ImGui::Combo("kind", &kind, "cloud to ground\0intra-cloud\0cloud to cloud\0");
    b.kind = lightning::Kind(kind);
    float bp = float(b.branch_probability), sp = float(b.angle_spread_deg), ie = float(std::log10(b.intensity));
    changed |= ImGui::SliderFloat("branch probability", &bp, 0.0f, 0.6f);
    changed |= ImGui::SliderFloat("angle spread (deg)", &sp, 0.0f, 40.0f);
    changed |= ImGui::SliderFloat("intensity (log10 W/sr/m)", &ie, 3.0f, 7.0f);
    b.branch_probability = bp, b.angle_spread_deg = sp, b.intensity = std::pow(10.0, double(ie));
    if (changed) shape_changed_ = true;
    ImGui::EndDisabled();
    return strike;
}

void DemoPanel::light_section(view::ViewOptions& opt, const view::FrameReport& rep, double dt) {
    ImGui::BeginDisabled(!separate_);
    ImGui::Checkbox("single scattering", &opt.components.single);
    ImGui::Checkbox("multiple scattering", &opt.components.multiple);
    ImGui::EndDisabled();
    if (!separate_ && ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
        ImGui::SetTooltip("this bake has no separate multiple-scattering component");
    ImGui::Checkbox("glow", &opt.settings.glow);
    ImGui::SameLine();
    ImGui::Checkbox("glare", &opt.settings.glare);
    ImGui::Checkbox("bolt", &opt.settings.bolt);
    ImGui::Checkbox("ground", &opt.settings.ground);
    ImGui::SameLine();
    ImGui::BeginDisabled(!opt.settings.ground);
    ImGui::Checkbox("cloud's light on it", &opt.settings.ground_scatter);
    ImGui::EndDisabled();
    if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
        ImGui::SetTooltip(
            "the flash light the cloud scatters onto the ground (presets that trace the strike's paths, and "
            "per_strike)");
    if (view_.scene().rain) {
        ImGui::SameLine();
        ImGui::Checkbox("rain", &opt.settings.rain);
        ImGui::BeginDisabled(!(opt.settings.rain && opt.settings.ground));
        ImGui::Checkbox("the ground's rain shadow from a map", &opt.settings.ground_rain_map);
        ImGui::EndDisabled();
        if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled))
            ImGui::SetTooltip(
                "the rain's transmittance toward the channel's ground lights tabulated once per channel (a sample "
                "per voxel); off: each ground pixel integrates its paths by 4 samples (at 1280x720 ~7 ms more "
                "of the march, and the ground beyond a shaft several percent off)");
    }
    if (view_.scene().cloud.detail) {
        ImGui::SameLine();
        ImGui::Checkbox("sub-voxel detail", &opt.settings.detail);
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "off: the march draws the cloud before its detail (the light keeps the detail's voxel means)");
    }
    static_light_panel(opt, view_.plan());
    if (has_lightning_ && view_.pipeline().quality().toward_camera && view_.scene().medium.g != 0.0)
        ImGui::TextWrapped(
            "solved strikes tallied toward the scene's camera (quality \"directions\": \"camera\"): "
            "exact from there only");
    exposure_panel(opt.settings, rep, dt);
    float scale = float(opt.settings.internal_scale);
    if (ImGui::SliderFloat("internal scale", &scale, 0.25f, 1.0f)) opt.settings.internal_scale = scale;
    if (opt.settings.internal_scale < 1.0) {
        ImGui::Checkbox("tone map before upsampling", &opt.settings.display_upsample);
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "the march's frame tone mapped at its own resolution and its display values upsampled, as "
                "games do (at 1280x720 the composite ~2.5 ms faster, as close to a march at every pixel); "
                "off: its radiance upsampled and tone mapped at every output pixel");
    }
    ImGui::Checkbox("temporal history", &opt.settings.temporal);
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "the march's light kept per group and rescaled by the flash's intensity: a still camera "
            "marches nothing while the flash only dims, a moving one a quarter of the pixels");
    if (opt.settings.temporal) {
        int mode = int(opt.settings.temporal_light);
        if (ImGui::Combo("moving camera's fill", &mode, "auto\0reproject\0upsample\0"))
            opt.settings.temporal_light = render::TemporalLight(mode);
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "a moving camera's pixels not marched: reprojected from the history, or upsampled from the "
                "marched quarter (nearer a fresh render and faster where the marched pixels are close together: "
                "1280x720 and above); auto picks by the march's pixel size on screen");
        int block = opt.settings.temporal_moving_block / 2;  // 0 auto, 1 a quarter, 2 a sixteenth
        if (ImGui::Combo("moving camera marches between flashes", &block, "auto\0a quarter\0a sixteenth\0"))
            opt.settings.temporal_moving_block = 2 * block;
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "while no flash lights the frame, a moving camera marches one pixel of each 2x2 block or of each "
                "4x4 (1280x720, detail and rain: 28 -> 17 ms, 1.2%% -> 3.3%% from a fresh render, 0.04 -> 0.13 "
                "levels as displayed); auto marches a sixteenth where its pixels are close together on screen "
                "(1280x720 and above); during a flash a quarter either way");
        bool flash_sixteenth = opt.settings.temporal_flash_block == 4;
        if (ImGui::Checkbox("a sixteenth during a flash too", &flash_sixteenth))
            opt.settings.temporal_flash_block = flash_sixteenth ? 4 : 2;
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "while a flash lights the frame, a moving camera marches a sixteenth where it marches one between "
                "flashes, instead of a quarter (1280x720 orbiting a return stroke with detail and rain: 39 -> 25 ms, "
                "0.11 -> 0.32 levels from a fresh render as displayed, in steps along the lit cloud's edges)");
        bool reshape_full = opt.settings.temporal_reshape == render::TemporalReshape::Full;
        if (ImGui::Checkbox("a light's new shape marched at every pixel", &reshape_full))
            opt.settings.temporal_reshape =
                reshape_full ? render::TemporalReshape::Full : render::TemporalReshape::Quarter;
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip(
                "a leader's growing front or a new stroke changes the flash's shape: off, a quarter of the pixels is "
                "marched and the flash's light upsampled from them, exact again once the shape holds (a leader at "
                "1280x720 with detail and rain: 52 ms, 2.0%% from a fresh render); on, every pixel (90 ms, exact)");
    }
}

void DemoPanel::frame_times(const view::FrameReport& rep) {
    ImGui::TextUnformatted("last 240 frames (ms)");
    frame_plots_.draw();
    if (ImGui::TreeNode("this frame's stages")) {
        ImGui::Text("bolt %.2f  sources %.2f  splat %.2f", rep.stages.bolt, rep.stages.sources, rep.stages.splat);
        ImGui::Text("accumulate %.2f  inverse Haar %.2f  strike light %.2f", rep.stages.accumulate,
                    rep.stages.inverse_haar, rep.stages.strike_light);
        ImGui::Text("upload %.2f  ray march %.2f  GPU total %.2f", rep.gpu.wall.upload, rep.gpu.wall.march,
                    rep.gpu.wall.total);
        static const char* const kSteps[] = {"off", "every pixel marched", "a quarter marched", "history reused"};
        ImGui::Text("temporal history: %s", kSteps[int(rep.gpu.temporal)]);
        ImGui::Text("programs compiled: %d", rep.gpu.programs_built);
        ImGui::TreePop();
    }
}

void DemoPanel::apply(double t, bool strike) {
    const double want_rate = autos_ ? double(rate_) : 0.0;
    if (has_lightning_ && (shape_changed_ || want_rate != lp_.schedule.strike_rate)) {
        // Bolt shape / schedule changed: new storm (bolts regenerate), same bake.
        lp_.schedule.strike_rate = want_rate;
        lp_.schedule.first_strike = t + 0.5;
        lp_.seed = std::uint64_t(seed_);
        view_.set_lightning(lp_);
        shape_changed_ = false;
        accuracy_.reset();
    }
    if (strike && has_lightning_) {
        // Nobody scheduled it: under a preset that solves strikes ahead it is lit the instant
        // way, its own progressive solve blended in from its first frame.
        view_.pipeline().strike_at(t, std::uint64_t(seed_++), /*known_ahead=*/false);
        accuracy_.reset();  // the reference belongs to one frame
    }
}

}  // namespace fulgur::app
