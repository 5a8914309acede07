// The direct solve (runtime.h): a frame's point sources straight through the bake's own
// solver, no virtual lights and no compression.
#include "runtime/runtime.h"

#include <cmath>

namespace fulgur::runtime {

transport::SourceField direct_solve(const scene::Scene& scene, const solve::Media& media,
                                    std::span<const transport::PointSource> sources, const Components& components) {
    const std::vector<glm::dvec3> dirs = transport::output_directions(scene.effective_directions());
    transport::SourceField out(media.lighting.density.geom, dirs);
    solve::SolveRequest rq;
    rq.single = components.single && scene.effects.single_scattering;
    rq.multiple = components.multiple && scene.effects.multiple_scattering;
    rq.skip_below = 0.0;  // the reference never drops light
    if (!rq.single && !rq.multiple) return out;
    std::vector<transport::PointSource> pts;
    pts.reserve(sources.size());
    for (const transport::PointSource& q : sources) {
        // As the splat: non-finite sources are skipped; zero ones add nothing.
        if (!std::isfinite(q.position.x) || !std::isfinite(q.position.y) || !std::isfinite(q.position.z) ||
            !std::isfinite(q.intensity) || q.intensity == 0.0)
            continue;
        pts.push_back(q);
    }
    if (pts.empty()) return out;
    const solve::Solution s = solve::solve(scene, media, pts, dirs, rq);
    auto add = [&](const transport::SourceField& f) {
        if (f.data.empty()) return;
        for (std::size_t i = 0; i < out.data.size(); ++i) out.data[i] += f.data[i];
    };
    if (rq.single) add(s.single);
    if (rq.multiple) add(s.multiple);
    return out;
}

}  // namespace fulgur::runtime
