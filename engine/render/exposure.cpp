// The automatic exposure (detail/exposure.h, docs/render.md "Exposure").
#include "render/detail/exposure.h"

#include <algorithm>
#include <cmath>

namespace fulgur::render::detail {

ExposureChoice choose_exposure(std::span<const std::uint32_t> bins, double log2_min, double bin_width,
                               const Settings& st) {
    ExposureChoice out;
    const double fallback = st.previous_exposure > 0.0 ? st.previous_exposure : st.exposure;
    // Log-average over the non-black pixels (bin 0 holds black and anything darker).
    double n = 0.0, sum_log2 = 0.0;
    for (std::size_t b = 1; b < bins.size(); ++b) {
        n += double(bins[b]);
        sum_log2 += double(bins[b]) * (log2_min + (double(b) + 0.5) * bin_width);
    }
    if (n <= 0.0) {
        out.metered = out.applied = fallback;
        return out;
    }
    const double log2_L = sum_log2 / n;
    out.log_average = std::exp2(log2_L);
    // The lit pixels: those at or above the frame's log-average (a dark sky around a lit
    // cloud would otherwise pull the key's luminance down and show the cloud too bright). As
    // everywhere here a bin's pixels are taken as spread evenly in log luminance over it, so
    // the bin holding the log-average counts with the share of it above, at that share's
    // centre: the lit pixels change smoothly as the log-average moves. Starting at a whole bin
    // instead moved the exposure by up to 0.4 stops between two frames of a fading flash.
    const std::size_t first_lit =
        std::size_t(std::clamp(std::floor((log2_L - log2_min) / bin_width), 1.0, double(bins.size() - 1)));
    const auto upper_edge = [&](std::size_t b) { return log2_min + double(b + 1) * bin_width; };
    // The lit part of each bin from first_lit up: its width in bins, (0, 1] (1 above first_lit).
    const auto lit_width = [&](std::size_t b) {
        return b == first_lit ? std::clamp((upper_edge(b) - log2_L) / bin_width, 0.0, 1.0) : 1.0;
    };
    double lit = 0.0, lit_log2 = 0.0;
    for (std::size_t b = first_lit; b < bins.size(); ++b) {
        const double part = lit_width(b);
        lit += part * double(bins[b]);
        lit_log2 += part * double(bins[b]) * (upper_edge(b) - 0.5 * part * bin_width);
    }
    // lit > 0: the log-average is a mean of the bins' centres, so the brightest non-empty bin
    // lies at or above first_lit with at least half of it lit.
    const double L_lit = std::exp2(lit_log2 / lit);
    const double key = 1.03 - 2.0 / (2.0 + std::log10(683.0 * L_lit + 1.0));
    double e = key / L_lit;
    // Highlights: the luminance exceeded by highlight_fraction of the lit pixels, within the
    // bin where the count from the top passes it, as if the bin's pixels were spread evenly in
    // log luminance over it. The bin's upper edge instead would move the exposure in whole bins
    // (a quarter stop) as a pixel or two crosses a count: pops between the frames of a fading
    // flash, and between two jitter patterns of one frame.
    const double wanted = st.highlight_fraction * lit;
    double above = 0.0;
    for (std::size_t b = bins.size(); b-- > first_lit;) {
        const double part = lit_width(b);
        const double count = part * double(bins[b]);
        if (above + count > wanted) {
            const double share = (wanted - above) / count;  // of this bin's lit part, from its upper edge: [0, 1)
            const double Lq = std::exp2(upper_edge(b) - share * part * bin_width);
            e = std::min(e, kHighlightExposed / Lq);
            break;
        }
        above += count;
    }
    out.metered = e * std::exp2(st.exposure_compensation);
    out.applied = out.metered;
    if (st.previous_exposure > 0.0 && st.adaptation_seconds > 0.0) {
        // Eye adaptation in log exposure: toward a brighter scene (lower exposure) with
        // darken_seconds, toward a darker one with brighten_seconds.
        const double tau = out.metered < st.previous_exposure ? st.darken_seconds : st.brighten_seconds;
        const double a = tau > 0.0 ? 1.0 - std::exp(-st.adaptation_seconds / tau) : 1.0;
        out.applied = st.previous_exposure * std::pow(out.metered / st.previous_exposure, a);
    }
    return out;
}

}  // namespace fulgur::render::detail
