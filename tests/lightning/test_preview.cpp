// Visual check: bolts drawn in a side view over the cloud (tests/.../output/lightning_preview/).
// The picture is for a human (docs/images/lightning-bolts.png is one of them); the checks
// here only make sure something bolt-like was drawn.
#include "lightning/lightning.h"
#include "support/test_support.h"
#include "synthetic.h"

#include <doctest/doctest.h>

using namespace fulgur;
using namespace fulgur::lightning;

namespace {
void draw(const std::filesystem::path& file, const core::Grid3<float>& cloud, const std::vector<Bolt>& bolts) {
    std::vector<LitSegment> lit;
    FlashState peak;
    peak.main_glow = peak.branch_glow = 1.0;  // the first return stroke's peak
    for (const Bolt& b : bolts) lit_segments(b, peak, lit);
    Box view{cloud.geom.origin, cloud.geom.upper()};
    int h = 0;
    const auto px = draw_side_view(lit, &cloud, view, 800, h);
    REQUIRE(h == 600);  // 12.8 km x 9.6 km at 800 px wide
    core::write_png(file, 800, h, 3, px);
    // Something bright was drawn: the bolt core saturates toward white.
    std::size_t bright = 0;
    for (std::size_t i = 0; i < px.size(); i += 3) bright += px[i] > 200 && px[i + 2] > 200;
    CHECK(bright > 500);  // a few km of channel, >= 1 px wide: well over 500 px
}
}  // namespace

TEST_CASE("preview: bolts of each kind drawn over the cloud") {
    const auto cloud = fixture::synthetic_storm(200.0);
    const auto dir = fulgur::test::scratch_dir("lightning_preview");
    for (Kind kind : {Kind::CloudToGround, Kind::IntraCloud, Kind::CloudToCloud}) {
        BoltParams p;
        p.kind = kind;
        const BoltGenerator gen(p, cloud);
        for (std::uint64_t seed : {1, 2, 3}) {
            draw(dir / (std::string(kind_name(kind)) + "_" + std::to_string(seed) + ".png"), cloud, {gen.generate(seed)});
        }
    }
}
