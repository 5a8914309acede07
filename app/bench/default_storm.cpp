// The default storm for the benchmarks (default_storm.h).
#include "bench/default_storm.h"

#include "bake/bake.h"

#include <filesystem>

namespace fulgur::bench {

DefaultStorm default_storm() {
    DefaultStorm d;
    d.scene = scene::load_scene(std::filesystem::path(FULGUR_SOURCE_ROOT) / "content/scenes/storm.json");
    d.scene.lightning.schedule.strike_rate = 0.0;
    d.density = scene::make_density(d.scene);
    const std::filesystem::path fgb = bake::default_fgb_path(d.scene);
    bake::bake_if_stale(d.scene, d.density, fgb);
    d.bases =
        std::make_unique<runtime::BakedBases>(runtime::BakedBases::load(fgb, bake::scene_key(d.scene, d.density)));
    return d;
}

}  // namespace fulgur::bench
