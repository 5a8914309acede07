// Parameter validation for fulgur::lightning. The ranges here are the ones the scene parser
// applies (engine/scene/scene.cpp); both reject NaN/Inf.
#include "lightning/lightning.h"

#include <array>
#include <cmath>
#include <sstream>
#include <string>

namespace fulgur::lightning {

std::string_view kind_name(Kind k) noexcept {
    // Indexed by Kind, in its declaration order.
    constexpr std::array<std::string_view, 3> kNames = {"cloud_to_ground", "intra_cloud", "cloud_to_cloud"};
    static_assert(std::size_t(Kind::CloudToCloud) == kNames.size() - 1);
    const auto i = std::size_t(k);
    return i < kNames.size() ? kNames[i] : "unknown";
}

namespace {

struct Checker {
    std::string where;
    void range(std::string_view field, double v, double lo, double hi, bool lo_open = false,
               bool hi_open = false) const {
        const bool ok = std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
        if (ok) return;
        std::ostringstream os;
        os.precision(10);
        os << "value " << v << " is outside the allowed range " << (lo_open ? "(" : "[") << lo << ", " << hi
           << (hi_open ? ")" : "]");
        throw core::Error(where + "." + std::string(field), os.str());
    }
};

}  // namespace

void validate(const LightningParams& p, std::string_view where) {
    const Checker c{std::string(where)};
    const BoltParams& b = p.bolt;
    c.range("angle_mean", b.angle_mean_deg, 0.0, 90.0);
    c.range("angle_spread", b.angle_spread_deg, 0.0, 60.0);
    c.range("segment_length_mean", b.segment_length_mean, 1.0, 5000.0);
    c.range("segment_length_spread", b.segment_length_spread, 0.0, 5000.0);
    c.range("target_bias", b.target_bias, 0.0, 1.0);
    c.range("wander", b.wander, 0.0, 2.0);
    c.range("zigzag", b.zigzag, 0.0, 4.0);
    c.range("branches.probability", b.branch_probability, 0.0, 1.0);
    c.range("branches.angle_mean", b.branch_angle_mean_deg, 0.0, 90.0);
    c.range("branches.length_fraction", b.branch_length_fraction, 0.0, 1.0, true, false);
    c.range("branches.intensity_decay", b.branch_intensity_decay, 0.0, 1.0);
    c.range("branches.max_depth", double(b.max_depth), 0.0, 8.0);
    c.range("intensity", b.intensity, 0.0, 1e12);
    c.range("start_density_threshold", b.start_density_threshold, 0.0, 1.0, false, true);
    c.range("ground_height", b.ground_height, -1e4, 5e4);
    c.range("max_segments", double(b.max_segments), 1.0, 1e6);

    const TimingParams& t = p.timing;
    c.range("timing.leader_speed", t.leader_speed, 1e3, 1e8);
    c.range("timing.leader_brightness", t.leader_brightness, 0.0, 1.0);
    c.range("timing.rise_time", t.rise_time, 0.0, 0.01);
    c.range("timing.decay_time", t.decay_time, 0.0, 1.0, true, false);
    c.range("timing.restrikes", t.restrikes, 0.0, 20.0);
    c.range("timing.restrikes_max", double(t.restrikes_max), 0.0, 32.0);
    c.range("timing.restrike_interval", t.restrike_interval, 0.001, 1.0);
    c.range("timing.restrike_brightness", t.restrike_brightness, 0.0, 10.0);
    c.range("timing.dart_leader_speed", t.dart_leader_speed, 1e5, 1e9);
    c.range("timing.dark_threshold", t.dark_threshold, 0.0, 0.5, true, false);

    c.range("strike_rate", p.schedule.strike_rate, 0.0, 100.0);
    c.range("first_strike", p.schedule.first_strike, 0.0, 1e6);
}

}  // namespace fulgur::lightning
