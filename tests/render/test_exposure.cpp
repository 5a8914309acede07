// The automatic exposure's choice from a luminance histogram (render/detail/exposure.h).
#include "render/detail/exposure.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <vector>

using namespace fulgur::render;

namespace {

constexpr double kMin = -40.0, kWidth = 0.25;

// The bin of luminance L.
std::size_t bin(double L) { return std::size_t(std::floor((std::log2(L) - kMin) / kWidth)); }
// The luminance the choice attributes to that bin (its centre).
double centre(double L) { return std::exp2(kMin + (double(bin(L)) + 0.5) * kWidth); }
// The centre of that bin's upper half.
double upper_half(double L) { return std::exp2(kMin + (double(bin(L)) + 0.75) * kWidth); }
double key(double L) { return 1.03 - 2.0 / (2.0 + std::log10(683.0 * L + 1.0)); }

// The metered exposure before and after each of `count` pixels moves from bin b up to b + 1,
// one at a time.
std::vector<double> moving_up(std::vector<std::uint32_t> h, std::size_t b, int count, const Settings& st) {
    std::vector<double> e{detail::choose_exposure(h, kMin, kWidth, st).metered};
    for (int moved = 1; moved <= count; ++moved) {
        --h[b];
        ++h[b + 1];
        e.push_back(detail::choose_exposure(h, kMin, kWidth, st).metered);
    }
    return e;
}

// The largest change between consecutive exposures, in stops.
double largest_step(const std::vector<double>& e) {
    double worst = 0.0;
    for (std::size_t i = 1; i < e.size(); ++i) worst = std::max(worst, std::abs(std::log2(e[i] / e[i - 1])));
    return worst;
}

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

    // A uniform frame: its pixels taken as spread evenly in log over their bin, whose centre is
    // the log-average: the lit ones are the bin's upper half, exposure = key(L) / L at that
    // half's centre (the highlight level is then key < 3: no guard).
    for (double L : {1e-4, 1.0, 100.0}) {
        std::fill(h.begin(), h.end(), 0u);
        h[bin(L)] = 5000;
        const detail::ExposureChoice c = detail::choose_exposure(h, kMin, kWidth, st);
        CHECK(c.log_average == fulgur::test::rel(centre(L), 1e-12));
        CHECK(c.metered == fulgur::test::rel(key(upper_half(L)) / upper_half(L), 1e-12));
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
    // The 50-bin is where the count from the top passes 2% of the 10001 lit pixels (200.02):
    // 1 above it, so 199.02 of its 200 pixels, spread evenly in log over the bin, lie above the
    // highlight level, which is mapped to kHighlightExposed.
    const double share = (0.02 * 10001.0 - 1.0) / 200.0;
    CHECK(g.metered ==
          fulgur::test::rel(detail::kHighlightExposed / std::exp2(kMin + (double(bin(50.0) + 1) - share) * kWidth),
                            1e-12));
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

TEST_CASE("exposure: continuous in the counts, no quarter-stop pops as pixels cross a bin") {
    // A lit cloud under a dark sky whose highlights (300 pixels, 3% of the lit ones) brighten
    // one pixel at a time into the next bin up: the highlights' level moves by about a bin
    // width over the pixels that cross (0.25 / 300 stops a pixel, while the 2% point lies in
    // the bin). Taking a bin's upper edge, the exposure jumped by a whole bin, 0.25 stops, at
    // the pixel where the 2% point crossed the edge.
    std::vector<std::uint32_t> h(256, 0);
    Settings st;
    h[bin(1e-7)] = 60000;  // night sky
    h[bin(1.0)] = 9700;    // cloud
    const std::size_t b = bin(50.0);
    h[b] = 300;
    const std::vector<double> e = moving_up(h, b, 300, st);
    for (std::size_t i = 1; i < e.size(); ++i) CHECK(e[i] <= e[i - 1]);  // brighter highlights: never a higher exposure
    // 0.25 / 200 = 0.00125 stops a pixel where the 2% point (200 pixels) lies in the upper bin,
    // a little more while it lies in the lower one; a whole bin is 0.25.
    CHECK(largest_step(e) < 0.003);
}

TEST_CASE("exposure: continuous as the log-average crosses a bin holding many pixels") {
    // A cloud whose pixels brighten a pixel at a time from one bin into the next: the
    // log-average walks across the edge between them. Counting the bin that holds it whole,
    // the lit pixels lost the lower bin at once there and the exposure jumped (by 0.12 stops);
    // with its share above the log-average, the key moves by a small step per pixel.
    std::vector<std::uint32_t> h(256, 0);
    Settings st;
    st.highlight_fraction = 1e-9;  // the key alone (no pixel is a highlight past the brightest)
    const std::size_t b = bin(1.0);
    h[b] = 4000;
    const double worst = largest_step(moving_up(h, b, 4000, st));
    MESSAGE("largest step of the exposure from one pixel: " << worst << " stops");
    // Each pixel moves the log-average by 0.25 / 4000 of a stop and the lit pixels' by about
    // as much; a jump is a hundred times more.
    CHECK(worst < 0.001);
}
