// CPU preparation of the density texture: quantization and the empty-space distance field.
#include "render/detail/volume_prep.h"
#include "support/grids.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>

using namespace fulgur;

TEST_CASE("Chebyshev distance equals brute force") {
    core::Rng rng(3, 4);
    for (int trial = 0; trial < 4; ++trial) {
        const core::Int3 d{9 + trial, 7, 5 + 2 * trial};
        std::vector<std::uint8_t> occ(d.volume(), 0);
        const int n = trial == 3 ? 0 : 1 + trial * 3;  // the last trial: nothing occupied
        for (int i = 0; i < n; ++i) occ[rng.uniform_below(std::uint32_t(occ.size()))] = 1;
        const auto dist = render::detail::chebyshev_distance(occ, d);
        test::for_each_cell(d, [&](int x, int y, int z) {
            int best = 255;
            test::for_each_cell(d, [&](int qx, int qy, int qz) {
                if (occ[std::size_t(qx + d.x * (qy + d.y * qz))])
                    best = std::min(best, std::max({std::abs(qx - x), std::abs(qy - y), std::abs(qz - z)}));
            });
            REQUIRE(int(dist[std::size_t(x + d.x * (y + d.y * z))]) == best);
        });
    }
}

TEST_CASE("Chebyshev distance saturates at 255") {
    const core::Int3 d{300, 1, 1};
    std::vector<std::uint8_t> occ(300, 0);
    occ[0] = 1;
    const auto dist = render::detail::chebyshev_distance(occ, d);
    CHECK(dist[100] == 100);
    CHECK(dist[255] == 255);
    CHECK(dist[299] == 255);
}

TEST_CASE("density quantization") {
    CHECK(render::detail::quantize_density(0.0f) == 0);
    CHECK(render::detail::quantize_density(1.0f) == 255);
    CHECK(render::detail::quantize_density(2.0f) == 255);
    CHECK(render::detail::quantize_density(-1.0f) == 0);
    CHECK(render::detail::quantize_density(std::numeric_limits<float>::quiet_NaN()) == 0);
    CHECK(render::detail::quantize_density(0.2f) == 51);
    CHECK(render::detail::quantize_density(1.0f / 510.0f - 1e-6f) == 0);  // below half a level
    CHECK(render::detail::quantize_density(1.0f / 510.0f + 1e-6f) == 1);
}
