// The default storm (content/scenes/storm.json) as the benchmarks that run on it load it:
// strikes only where a benchmark places them, the density made, the bases baked beside the
// scene when stale and loaded.
#pragma once

#include "core/core.h"
#include "runtime/runtime.h"
#include "scene/scene.h"

#include <memory>

namespace fulgur::bench {

struct DefaultStorm {
    scene::Scene scene;  ///< lightning.schedule.strike_rate 0: no strike the benchmark did not place
    core::Grid3<float> density;
    std::unique_ptr<runtime::BakedBases> bases;
};

DefaultStorm default_storm();

}  // namespace fulgur::bench
