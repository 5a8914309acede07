// Strike scheduling: a deterministic Poisson process per storm seed plus strikes on demand,
// and the per-frame queries (active strikes, point sources, lit stretches).
#include "lightning/lightning.h"

#include <algorithm>
#include <cmath>

namespace fulgur::lightning {

namespace {
constexpr std::uint64_t kArrivalStream = 0x41525249ULL;  // "ARRI"
constexpr std::uint64_t kScheduledTag = 0x53434845ULL;   // "SCHE"
constexpr std::uint64_t kOnDemandTag = 0x4F4E4445ULL;    // "ONDE"
constexpr std::uint64_t kTimingTag = 0x54494D45ULL;      // "TIME"
}  // namespace

Storm::Storm(const LightningParams& p, const core::Grid3<float>& density, std::optional<Box> domain)
    : p_((validate(p), p)),
      gen_(p.bolt, density, domain),
      next_arrival_(p.schedule.first_strike),
      arrivals_(core::hash_seed(p.seed, kArrivalStream), 0) {}

std::size_t Storm::add(double t, std::uint64_t seed) {
    Entry e;
    e.strike.time = t;
    e.strike.seed = seed;
    e.bolt = std::make_unique<Bolt>(gen_.generate(seed));
    e.strike.profile = make_flash_profile(*e.bolt, p_.timing, core::hash_seed(seed, kTimingTag));
    max_duration_ = std::max(max_duration_, e.strike.profile.duration);
    const std::size_t index = strikes_.size();
    strikes_.push_back(std::move(e));
    // Keep by_time_ sorted by start time; equal times keep insertion order.
    const auto pos = std::upper_bound(by_time_.begin(), by_time_.end(), t,
                                      [&](double v, std::size_t i) { return v < strikes_[i].strike.time; });
    by_time_.insert(pos, index);
    live_.push_back(index);
    return index;
}

std::size_t Storm::strike_at(double t, std::optional<std::uint64_t> seed) {
    if (!std::isfinite(t)) throw core::Error("lightning: strike time", "must be a finite time in seconds");
    const std::uint64_t s = seed ? *seed : core::hash_seed(p_.seed, kOnDemandTag, on_demand_++);
    return add(t, s);
}

void Storm::schedule_until(double t) {
    if (!(p_.schedule.strike_rate > 0.0)) return;
    while (next_arrival_ <= t) {
        add(next_arrival_, core::hash_seed(p_.seed, kScheduledTag, scheduled_));
        ++scheduled_;
        // Exponential inter-arrival time; 1 - u is in (0, 1], so the log is finite.
        next_arrival_ += -std::log(1.0 - arrivals_.uniform()) / p_.schedule.strike_rate;
    }
}

std::span<const std::size_t> Storm::active(double t) {
    active_.clear();
    if (!std::isfinite(t)) return {};
    schedule_until(t);
    // Strikes starting after t are not active; those starting before t - max_duration_ are over.
    auto it = std::upper_bound(by_time_.begin(), by_time_.end(), t,
                               [&](double v, std::size_t i) { return v < strikes_[i].strike.time; });
    while (it != by_time_.begin()) {
        --it;
        const Strike& s = strikes_[*it].strike;
        if (s.time < t - max_duration_) break;
        if (t < s.end()) active_.push_back(*it);
    }
    std::reverse(active_.begin(), active_.end());
    // Drop the bolts of strikes that are over by the latest time asked about; they are
    // regenerated (bit-identically) if an earlier time is queried again.
    if (t > latest_query_) {
        latest_query_ = t;
        std::size_t w = 0;
        for (const std::size_t j : live_) {
            Entry& e = strikes_[j];
            if (e.strike.end() <= latest_query_)
                e.bolt.reset();
            else
                live_[w++] = j;
        }
        live_.resize(w);
    }
    return active_;
}

std::vector<std::size_t> Storm::starting(double t0, double t1) {
    std::vector<std::size_t> out;
    if (!std::isfinite(t0) || !std::isfinite(t1) || !(t1 > t0)) return out;
    schedule_until(t1);
    auto it = std::lower_bound(by_time_.begin(), by_time_.end(), t0,
                               [&](std::size_t i, double v) { return strikes_[i].strike.time < v; });
    for (; it != by_time_.end() && strikes_[*it].strike.time < t1; ++it) out.push_back(*it);
    return out;
}

const Bolt& Storm::bolt(std::size_t i) {
    FULGUR_ASSERT(i < strikes_.size(), "strike index out of range");
    Entry& e = strikes_[i];
    if (!e.bolt) {
        e.bolt = std::make_unique<Bolt>(gen_.generate(e.strike.seed));
        live_.push_back(i);
    }
    return *e.bolt;
}

bool Storm::lit(double t, std::vector<LitSegment>& out) {
    out.clear();
    const std::span<const std::size_t> span = active(t);
    const std::vector<std::size_t> act(span.begin(), span.end());
    for (const std::size_t i : act) {
        const Strike& s = strikes_[i].strike;
        lit_segments(bolt(i), flash_state(s.profile, p_.timing, t - s.time), out);
    }
    return !out.empty();
}

bool Storm::point_sources(double t, double max_spacing, std::vector<transport::PointSource>& out) {
    out.clear();
    std::vector<LitSegment> lit_now;
    if (!lit(t, lit_now)) return false;
    append_point_sources(lit_now, max_spacing, out);
    return !out.empty();
}

}  // namespace fulgur::lightning
