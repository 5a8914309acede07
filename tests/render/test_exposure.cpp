// The automatic exposure's choice from a luminance histogram (render/detail/exposure.h).
#include "render/detail/exposure.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

using namespace fulgur::render;

namespace {

constexpr double kMin = -40.0, kWidth = 0.25;

// The bin of luminance L.
std::size_t bin(double L) { return std::size_t(std::floor((std::log2(L) - kMin) / kWidth)); }
// The luminance the choice attributes to that bin (its centre).
double centre(double L) { return std::exp2(kMin + (double(bin(L)) + 0.5) * kWidth); }
double key(double L) { return 1.03 - 2.0 / (2.0 + std::log10(683.0 * L + 1.0)); }

}  // namespace

TEST_CASE("exposure: the key of a uniform frame, dim scenes dimmer; the highlight guard; the fallbacks") {
    std::vector<std::uint32_t> h(256, 0);
    Settings st;
    st.exposure = 0.7;
    // All black: nothing to meter, the manual exposure (or the previous one) stays.
    h[0] = 1000;
    CHECK(detail::choose_exposure(h, kMin, kWidth, st).applied == 0.7);
    st.previous_exposure = 3.0;
    CHECK(detail::choose_exposure(h, kMin, kWidth, st).applied == 3.0);
    st.previous_exposure = 0.0;

    // A uniform frame: exposure = key(L) / L (the highlight level is then key < 3: no guard).
    for (double L : {1e-4, 1.0, 100.0}) {
        std::fill(h.begin(), h.end(), 0u);
        h[bin(L)] = 5000;
        const detail::ExposureChoice c = detail::choose_exposure(h, kMin, kWidth, st);
        CHECK(c.log_average == fulgur::test::rel(centre(L), 1e-12));
        CHECK(c.metered == fulgur::test::rel(key(centre(L)) / centre(L), 1e-12));
    }
    // Dim scenes are shown dimmer: the exposed log-average (the key) grows with luminance.
    CHECK(key(1e-4) < key(1.0));
    CHECK(key(1.0) < key(100.0));

    // A dark sky around a uniformly lit cloud: the key is the cloud's (the lit pixels, at or
    // above the frame's log-average), not pulled down by the sky.
    std::fill(h.begin(), h.end(), 0u);
    h[bin(1e-7)] = 60000;  // night sky
    h[bin(1.0)] = 10000;   // cloud
    CHECK(detail::choose_exposure(h, kMin, kWidth, st).metered ==
          fulgur::test::rel(key(centre(1.0)) / centre(1.0), 1e-12));

    // A dark background with a lit cloud: the key alone would put the cloud far past white;
    // the guard puts the top 2% of the lit pixels at kHighlightExposed.
    std::fill(h.begin(), h.end(), 0u);
    h[bin(1e-7)] = 60000;  // night sky
    h[bin(1.0)] = 9800;    // cloud
    h[bin(50.0)] = 200;    // near the channel: 2% of the lit pixels
    h[bin(400.0)] = 1;     // the brightest pixel
    const detail::ExposureChoice g = detail::choose_exposure(h, kMin, kWidth, st);
    // The 50-bin is where more than 2% of the lit pixels lie above: its upper edge is mapped
    // to the highlight level, so at most 2% of the lit pixels are brighter.
    CHECK(g.metered ==
          fulgur::test::rel(detail::kHighlightExposed / std::exp2(kMin + double(bin(50.0) + 1) * kWidth), 1e-12));
    CHECK(g.metered * centre(1.0) < detail::kHighlightExposed);
    CHECK(g.metered * centre(400.0) < 10.0 * detail::kWhiteExposed);  // a single pixel may clip

    // Compensation in stops; adaptation: at once toward a brighter scene, over
    // brighten_seconds toward a darker one (in log exposure).
    st.exposure_compensation = -1.0;
    CHECK(detail::choose_exposure(h, kMin, kWidth, st).metered == fulgur::test::rel(0.5 * g.metered, 1e-12));
    st.exposure_compensation = 0.0;
    st.previous_exposure = 10.0 * g.metered;  // coming from a darker frame
    st.adaptation_seconds = 0.016;
    CHECK(detail::choose_exposure(h, kMin, kWidth, st).applied == fulgur::test::rel(g.metered, 1e-12));
    st.previous_exposure = 0.1 * g.metered;  // after a flash
    const double a = 1.0 - std::exp(-0.016 / st.brighten_seconds);
    CHECK(detail::choose_exposure(h, kMin, kWidth, st).applied ==
          fulgur::test::rel(st.previous_exposure * std::pow(10.0, a), 1e-12));
}
