#include "view_cli.h"

#include "progress.h"

#include <cstdio>
#include <sstream>

namespace fulgur::app {

std::filesystem::path ensure_baked(const scene::Scene& s, const core::Grid3<float>& density,
                                   const std::optional<std::filesystem::path>& explicit_fgb) {
    return view::ensure_baked(s, density, explicit_fgb, make_progress_printer(stderr, "lights"),
                              [](const std::filesystem::path& fgb, const std::string& why) {
                                  std::fprintf(stderr, "baking %s (%s)\n", fgb.string().c_str(), why.c_str());
                              });
}

sky::ScenePlan plan_and_print(const scene::Scene& s, const core::Grid3<float>& density, std::FILE* out) {
    bake::PlanOptions po;
    po.estimate = false;
    sky::ScenePlan plan = sky::plan_scene(s, density, po);
    for (const std::string& r : plan.reasons) std::fprintf(out, "plan: %s\n", r.c_str());
    return plan;
}

std::optional<std::filesystem::path> bases_for(const sky::ScenePlan& plan, const scene::Scene& s,
                                               const core::Grid3<float>& density,
                                               const std::optional<std::filesystem::path>& explicit_fgb) {
    if (plan.lightning) return ensure_baked(s, density, explicit_fgb);
    return view::bases_for(plan, s, density, explicit_fgb);
}

SceneDensity load_density(const scene::Scene& s) {
    SceneDensity d;
    d.density = scene::make_undetailed_density(s);
    if (s.cloud.detail) {
        d.undetailed = std::move(d.density);
        d.density = scene::add_detail(s, *d.undetailed);
    }
    return d;
}

view::StaticSetup static_setup(const sky::ScenePlan& plan, std::FILE* out, const SceneDensity* d) {
    view::StaticSetup setup;
    setup.plan = plan;
    if (d && d->undetailed) setup.undetailed_density = &*d->undetailed;
    setup.say = [out](const std::string& m) { std::fprintf(out, "%s\n", m.c_str()); };
    return setup;
}

std::string timings_json(const view::FrameReport& r, int width, int height, const char* name) {
    std::ostringstream o;
    o.precision(4);
    o << "{\"name\":\"" << name << "\",\"width\":" << width << ",\"height\":" << height
      << ",\"lit\":" << (r.lit ? "true" : "false") << ",\"bolt_ms\":" << r.stages.bolt
      << ",\"sources_ms\":" << r.stages.sources << ",\"splat_ms\":" << r.stages.splat
      << ",\"accumulate_ms\":" << r.stages.accumulate << ",\"inverse_haar_ms\":" << r.stages.inverse_haar
      << ",\"upload_ms\":" << r.gpu.wall.upload << ",\"resolve_ms\":" << r.gpu.wall.resolve
      << ",\"glow_ms\":" << r.gpu.wall.glow << ",\"march_ms\":" << r.gpu.wall.march
      << ",\"bolt_draw_ms\":" << r.gpu.wall.bolt << ",\"glare_ms\":" << r.gpu.wall.glare
      << ",\"composite_ms\":" << r.gpu.wall.composite << ",\"gpu_total_ms\":" << r.gpu.wall.total
      << ",\"frame_ms\":" << r.wall_ms << ",\"internal_width\":" << r.gpu.internal_width
      << ",\"internal_height\":" << r.gpu.internal_height << ",\"exposure\":" << r.gpu.exposure
      << ",\"metered_exposure\":" << r.gpu.metered_exposure << "}";
    return o.str();
}

}  // namespace fulgur::app
