// Flash timing: the temporal profile of a strike and the lit stretches of a bolt at time t.
//
// Profile (t relative to the strike's start):
//   [0, T_L)            stepped leader: the channel appears from the start point at
//                       leader_speed, glowing at leader_brightness (branches grow with it:
//                       a segment is revealed once the front passes its path position).
//   stroke k at s_k     return stroke (k = 0, s_0 = T_L) or restrike (k >= 1): the glow
//                       rises linearly from the leader level to the peak P_k in rise_time,
//                       then decays as P_k exp(-(t - s_k - rise)/decay_time) until it falls
//                       below dark_threshold, after which it is exactly zero.
//   [s_k - T_D, s_k)    dart leader before a restrike: re-lights the main channel only,
//                       top-down, at dart_leader_speed (T_D = main length / speed).
// Branches glow with stroke 0 only (restrikes follow the main channel: Rakov & Uman 2003).
#include "lightning/lightning.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>

namespace fulgur::lightning {

namespace {
constexpr std::uint64_t kTimingStream = 0x54494D45ULL;  // "TIME"

int poisson(core::Rng& r, double mean, int cap) {
    // Knuth's product method; mean <= 20 (validated), so exp(-mean) is far from underflow.
    const double limit = std::exp(-mean);
    int k = 0;
    double prod = r.uniform();
    while (prod > limit && k < cap) {
        ++k;
        prod *= r.uniform();
    }
    return k;
}
}  // namespace

FlashProfile make_flash_profile(const Bolt& bolt, const TimingParams& p, std::uint64_t seed) {
    core::Rng r(seed, kTimingStream);
    FlashProfile f;
    f.leader_duration = bolt.main_length / p.leader_speed;
    f.dart_duration = bolt.main_length / p.dart_leader_speed;
    const int restrikes = poisson(r, p.restrikes, p.restrikes_max);
    double onset = f.leader_duration;
    for (int k = 0; k <= restrikes; ++k) {
        double peak = 1.0;
        if (k > 0) {
            // Log-normal interval around the median (sigma 0.4 in log space, a spread like
            // the measured inter-stroke intervals), never shorter than the dart leader plus
            // the previous stroke's rise.
            const double interval = p.restrike_interval * std::exp(0.4 * r.normal());
            onset += std::max(interval, f.dart_duration + p.rise_time + 1e-4);
            peak = p.restrike_brightness * (0.6 + 0.8 * r.uniform());
        }
        const double end = peak > p.dark_threshold
                               ? onset + p.rise_time + p.decay_time * std::log(peak / p.dark_threshold)
                               : onset + p.rise_time;
        f.stroke_onset.push_back(onset);
        f.stroke_peak.push_back(peak);
        f.stroke_end.push_back(end);
        f.duration = std::max(f.duration, end);
    }
    return f;
}

FlashState flash_state(const FlashProfile& f, const TimingParams& p, double t) noexcept {
    FlashState s;
    if (!(t >= 0.0) || !(t < f.duration)) return s;  // also catches NaN
    if (t < f.leader_duration) {
        s.leader_glow = p.leader_brightness;
        s.leader_front = t * p.leader_speed;
        s.leader_main_only = false;
    }
    for (std::size_t k = 0; k < f.stroke_onset.size(); ++k) {
        const double on = f.stroke_onset[k];
        if (k > 0 && t >= on - f.dart_duration && t < on && f.dart_duration > 0.0) {
            s.leader_glow = p.leader_brightness;
            s.leader_front = (t - (on - f.dart_duration)) * p.dart_leader_speed;
            s.leader_main_only = true;
        }
        if (t < on || t >= f.stroke_end[k]) continue;
        const double dt = t - on;
        double g;
        if (dt < p.rise_time) {
            const double x = dt / p.rise_time;
            g = p.leader_brightness + (f.stroke_peak[k] - p.leader_brightness) * x;
        } else {
            g = f.stroke_peak[k] * std::exp(-(dt - p.rise_time) / p.decay_time);
        }
        s.main_glow += g;
        if (k == 0) s.branch_glow = g;
    }
    return s;
}

void lit_segments(const Bolt& bolt, const FlashState& s, std::vector<LitSegment>& out) {
    if (!s.active()) return;
    for (const Segment& g : bolt.segments) {
        if (!(g.intensity != 0.0)) continue;
        const double glow = g.depth == 0 ? s.main_glow : s.branch_glow;
        double lead_frac = 0.0;
        if (s.leader_glow > 0.0 && (!s.leader_main_only || g.depth == 0) && g.path_start < s.leader_front) {
            const double len = g.length();
            lead_frac = len > 0.0 ? std::min(1.0, (s.leader_front - g.path_start) / len) : 1.0;
        }
        if (lead_frac >= 1.0) {
            out.push_back({g.a, g.b, g.intensity * (glow + s.leader_glow), g.depth});
            continue;
        }
        if (glow > 0.0) out.push_back({g.a, g.b, g.intensity * glow, g.depth});
        if (lead_frac > 0.0) out.push_back({g.a, g.a + lead_frac * (g.b - g.a), g.intensity * s.leader_glow, g.depth});
    }
}

double append_point_sources(std::span<const LitSegment> lit, double max_spacing,
                            std::vector<transport::PointSource>& out) {
    FULGUR_ASSERT(std::isfinite(max_spacing) && max_spacing > 0.0, "point-source spacing must be finite and positive");
    core::CompensatedSum total;
    for (const LitSegment& l : lit) {
        const glm::dvec3 delta = l.b - l.a;
        const double len = glm::length(delta);
        if (!(len > 0.0) || l.intensity == 0.0) continue;  // no length or no light: no energy
        const double pieces = std::ceil(len / max_spacing);
        FULGUR_ASSERT(pieces < 1e7, "point-source spacing is absurdly small for this segment");
        const std::size_t n = std::max<std::size_t>(1, std::size_t(pieces));
        const double q = l.intensity * len / double(n);
        const double inv = 1.0 / double(n);
        for (std::size_t i = 0; i < n; ++i) {
            out.push_back({l.a + ((double(i) + 0.5) * inv) * delta, q});
            total.add(q);
        }
    }
    return total.value();
}

FlashParts split_leaders(const FlashState& s) noexcept {
    FlashParts p{s, s};
    p.leaders.main_glow = p.leaders.branch_glow = 0.0;
    p.strokes.leader_glow = 0.0;
    return p;
}

}  // namespace fulgur::lightning
