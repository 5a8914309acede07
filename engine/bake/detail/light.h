// One virtual light's part of a bake (internal to engine/bake): its bases as the file stores
// them, solved, compressed and encoded with the figures the report sums.
#pragma once

#include "bake/bake.h"

namespace fulgur::bake::detail {

/// Light l solved, compressed and encoded on the calling thread: one job of the bake.
LightResult bake_one(const scene::Scene& s, const solve::Media& media, const Plan& plan,
                     basis::HaarTransform<double>& haar, std::uint32_t l);

}  // namespace fulgur::bake::detail
