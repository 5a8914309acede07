// The Reed-Wyvill bolt generator (Reed & Wyvill 1994, "Visual simulation of lightning"),
// extended with kinds (cloud-to-ground, intra-cloud, cloud-to-cloud) and a target bias that
// acts only on the azimuth of each turn, so the turn-angle distribution is exactly
// |N(angle_mean, angle_spread)| whatever the bias.
//
// Random streams (core::Rng(seed, stream)): 0 = main channel, 1 = branch decisions,
// 2 + k = walk of the k-th branch, kStartStream = start point. The main channel therefore
// does not change when only branch parameters change.
#include "lightning/lightning.h"

#include <glm/geometric.hpp>

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <deque>
#include <numbers>
#include <string>

namespace fulgur::lightning {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr std::uint64_t kStartStream = 0x5354415254ULL;  // "START"

glm::dvec3 turn(const glm::dvec3& d, const glm::dvec3& u, const glm::dvec3& v, double theta, double phi) noexcept {
    const glm::dvec3 r = std::cos(theta) * d + std::sin(theta) * (std::cos(phi) * u + std::sin(phi) * v);
    return glm::normalize(r);
}

/// The walk's random draws and geometry, shared by the main channel and the branches.
struct Walk {
    const BoltParams& p;
    const Box& box;
    const core::Grid3<float>& density;
    double theta_mean = 0.0, theta_sd = 0.0;  ///< turn angle's mean and spread (radians)
    /// Candidate turns per step: intra-cloud bolts try several and keep the first whose end
    /// lies in cloud denser than follow_threshold (else the densest); others take the first.
    int follow_tries = 1;
    double follow_threshold = 0.0;

    double length(core::Rng& r) const {
        const double m = p.segment_length_mean, s = p.segment_length_spread;
        for (int i = 0; i < 16; ++i) {
            const double x = m + s * r.normal();
            if (x >= 0.2 * m && x <= 3.0 * m) return x;
        }
        return m;
    }

    static double angle(core::Rng& r, double mean_rad, double spread_rad) {
        double t = std::fabs(mean_rad + spread_rad * r.normal());
        t = std::fmod(t, 2.0 * std::numbers::pi);
        return t > std::numbers::pi ? 2.0 * std::numbers::pi - t : t;
    }

    /// Azimuth of a turn of d: uniform over a window of half-width (1 - bias) * pi centred
    /// on a preferred azimuth; bias 0: uniform. The preferred sideways direction is the aim
    /// (`toward`, unit) seen from d, plus `zigzag` times sin(angle_mean) times the opposite of
    /// the previous turn's sideways direction `prev_side` (so turns alternate and the walk
    /// zig-zags about the aim instead of drifting in arcs). Only the azimuth is biased: the
    /// turn angle keeps its distribution exactly.
    double azimuth(core::Rng& r, const glm::dvec3& d, const glm::dvec3& u, const glm::dvec3& v,
                   const glm::dvec3& toward, double bias, const glm::dvec3& prev_side) const {
        const double x = r.uniform();
        const glm::dvec3 ps = prev_side - glm::dot(prev_side, d) * d;
        const glm::dvec3 tp = toward - glm::dot(toward, d) * d - p.zigzag * std::sin(p.angle_mean_deg * kDeg) * ps;
        if (!(bias > 0.0) || !(glm::length(tp) > 1e-12)) return 2.0 * std::numbers::pi * x;
        const double phi_t = std::atan2(glm::dot(tp, v), glm::dot(tp, u));
        const double b = bias;
        return phi_t + (1.0 - b) * std::numbers::pi * (2.0 * x - 1.0);
    }

    /// One turn of the walk at `pos` before a step of `len`: the heading `d` turns by a drawn
    /// angle toward `aim` (azimuth biased by `bias`), following the cloud's density as
    /// follow_tries says; `side` is the previous turn's sideways direction, updated.
    void turn_toward(core::Rng& r, const glm::dvec3& pos, double len, const glm::dvec3& aim, double bias, glm::dvec3& d,
                     glm::dvec3& side) const;
};

/// Unit sideways component of the turn from d0 to d1 (zero for no turn).
glm::dvec3 side_of(const glm::dvec3& d0, const glm::dvec3& d1) noexcept {
    const glm::dvec3 w = d1 - glm::dot(d1, d0) * d0;
    const double l = glm::length(w);
    return l > 1e-12 ? w / l : glm::dvec3(0.0);
}

void Walk::turn_toward(core::Rng& r, const glm::dvec3& pos, double len, const glm::dvec3& aim, double bias,
                       glm::dvec3& d, glm::dvec3& side) const {
    glm::dvec3 u, v;
    core::orthonormal_basis(d, u, v);
    const double theta = angle(r, theta_mean, theta_sd);
    glm::dvec3 best_d = d;
    double best_rho = -1.0;
    for (int k = 0; k < follow_tries; ++k) {
        const glm::dvec3 c = turn(d, u, v, theta, azimuth(r, d, u, v, aim, bias, side));
        const double rho = follow_tries > 1 ? double(density.sample(pos + len * c)) : 0.0;
        if (rho > best_rho) best_rho = rho, best_d = c;
        if (rho >= follow_threshold) break;
    }
    side = side_of(d, best_d);
    d = best_d;
}

/// Parameter t in (0, 1] where the segment from `a` (inside) along `delta` leaves the box,
/// or > 1 if it stays inside.
double exit_fraction(const Box& box, const glm::dvec3& a, const glm::dvec3& delta) noexcept {
    double t = 2.0;
    for (int k = 0; k < 3; ++k) {
        if (delta[k] > 0.0 && a[k] + delta[k] > box.hi[k]) t = std::min(t, (box.hi[k] - a[k]) / delta[k]);
        if (delta[k] < 0.0 && a[k] + delta[k] < box.lo[k]) t = std::min(t, (box.lo[k] - a[k]) / delta[k]);
    }
    return std::max(t, 0.0);
}

glm::dvec3 clamp_to(const Box& box, glm::dvec3 p) noexcept { return glm::clamp(p, box.lo, box.hi); }

}  // namespace

double Segment::length() const noexcept { return glm::length(b - a); }

double Bolt::total_length() const noexcept {
    core::CompensatedSum s;
    for (const Segment& g : segments) s.add(g.length());
    return s.value();
}

// ---------------------------------------------------------------------------------------

StartSampler::StartSampler(const core::Grid3<float>& density, double threshold, double min_height)
    : geom_(density.geom) {
    float max_density = 0.0f;
    const core::Int3 n = density.dims();
    for (int k = 0; k < n.z; ++k) {
        if (!(geom_.centre(0, 0, k).z > min_height)) continue;
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i) {
                const float rho = density.at(i, j, k);
                if (rho > max_density) max_density = rho;  // NaN compares false: ignored
                if (double(rho) > threshold) cells_.push_back(std::uint32_t(geom_.index(i, j, k)));
            }
    }
    if (cells_.empty())
        throw core::Error("lightning.start_density_threshold",
                          "no voxel of the cloud density above z = " + core::format_number(min_height, 8) +
                              " m exceeds the start threshold " + core::format_number(threshold, 8) +
                              " (the maximum density there is " + core::format_number(max_density, 8) +
                              "); a bolt needs cloud to start in: lower the threshold or check the cloud");
}

glm::dvec3 StartSampler::sample(core::Rng& rng) const {
    const std::uint32_t cell = cells_[rng.uniform_below(std::uint32_t(cells_.size()))];
    const core::Int3 c = geom_.unindex(cell);
    const glm::dvec3 jitter(rng.uniform(), rng.uniform(), rng.uniform());
    return geom_.origin + (glm::dvec3(c.x, c.y, c.z) + jitter) * geom_.voxel_size;
}

// ---------------------------------------------------------------------------------------

namespace {
Box default_domain(const BoltParams& p, const core::Grid3<float>& density, std::optional<Box> domain) {
    core::validate_geometry(density.geom, "lightning: cloud density grid");
    Box b;
    if (domain) {
        b = *domain;
        for (int k = 0; k < 3; ++k)
            if (!std::isfinite(b.lo[k]) || !std::isfinite(b.hi[k]) || !(b.lo[k] < b.hi[k]))
                throw core::Error("lightning: domain", "the domain box must be finite with lo < hi on every axis");
    } else {
        b.lo = density.geom.origin;
        b.hi = density.geom.upper();
    }
    // The floor of the domain is the ground: a caller's box reaching below it is cut there;
    // one whose floor is above the ground could not hold a cloud-to-ground bolt.
    if (domain && p.ground_height < b.lo.z)
        throw core::Error("lightning.ground_height",
                          "the ground (z = " + core::format_number(p.ground_height, 8) +
                              " m) lies below the domain's floor (z = " + core::format_number(b.lo.z, 8) + " m)");
    b.lo.z = p.ground_height;
    if (!(p.ground_height + p.segment_length_mean < b.hi.z))
        throw core::Error("lightning.ground_height",
                          "the ground (z = " + core::format_number(p.ground_height, 8) +
                              " m) must lie more than a segment below the top of the domain (z = " +
                              core::format_number(b.hi.z, 8) + " m)");
    return b;
}

LightningParams wrap(const BoltParams& b) {
    LightningParams p;
    p.bolt = b;
    return p;
}
}  // namespace

BoltGenerator::BoltGenerator(const BoltParams& p, const core::Grid3<float>& density, std::optional<Box> domain)
    : p_((validate(wrap(p)), p)),
      density_(&density),
      domain_(default_domain(p, density, domain)),
      sampler_(density, p.start_density_threshold, std::max(domain_.lo.z, p.ground_height) + p.segment_length_mean) {}

Bolt BoltGenerator::generate(std::uint64_t seed) const {
    core::Rng r(seed, kStartStream);
    glm::dvec3 s = sampler_.sample(r);
    // The sampler's voxels may stick out of a caller-given domain: pull the start inside.
    s = clamp_to(domain_, s);
    s.z = std::max(s.z, p_.ground_height + 0.5 * p_.segment_length_mean);
    return generate_from(s, seed);
}

namespace {

glm::dvec3 toward(const glm::dvec3& from, const glm::dvec3& to) noexcept {
    const glm::dvec3 t = to - from;
    const double l = glm::length(t);
    return l > 0.0 ? t / l : glm::dvec3(0.0, 0.0, -1.0);
}

/// One bolt's construction, step by step: its target, the waypoints of its main channel,
/// the main channel's walk, then the branches. Each step draws from its own RNG stream in a
/// fixed order, so a seed gives the same bolt bit for bit.
struct BoltBuilder {
    const BoltParams& p;
    const Box& box;
    const core::Grid3<float>& density;
    const StartSampler& sampler;
    const Walk& walk;
    const glm::dvec3 start;
    Bolt& bolt;
    const bool cg = p.kind == Kind::CloudToGround;
    const glm::dvec3 inset = 0.01 * (box.hi - box.lo);

    void choose_target(core::Rng& rng);
    std::vector<glm::dvec3> waypoints(core::Rng& rng) const;
    void main_channel(core::Rng& rng, const std::vector<glm::dvec3>& waypoints);
    void close_to_ground(const glm::dvec3& pos, double& path);
    void branches(std::uint64_t seed);
};

// Cloud-to-ground: a ground point scattered about the start by ~0.35 of its height.
// Intra-cloud: a far point of the cloud at a similar height; cloud-to-cloud: a far point
// reached through clear air. The best of 24 draws from the start sampler.
void BoltBuilder::choose_target(core::Rng& rng) {
    const double ground = p.ground_height;
    if (cg) {
        const double h = start.z - ground;
        const double r = std::fabs(0.35 * h * rng.normal());
        const double a = 2.0 * std::numbers::pi * rng.uniform();
        bolt.target = glm::dvec3(std::clamp(start.x + r * std::cos(a), box.lo.x + inset.x, box.hi.x - inset.x),
                                 std::clamp(start.y + r * std::sin(a), box.lo.y + inset.y, box.hi.y - inset.y), ground);
        return;
    }
    double best = -1e300;
    bolt.target = start;
    for (int i = 0; i < 24; ++i) {
        const glm::dvec3 c = clamp_to(box, sampler.sample(rng));
        const double hd = std::hypot(c.x - start.x, c.y - start.y), dz = std::fabs(c.z - start.z);
        double score = hd - dz;
        if (p.kind == Kind::CloudToCloud) {
            // Prefer a target across clear air: another cloud, or another part of a
            // concave one (tower to anvil); a convex lone cloud falls back to distance.
            int air = 0;
            for (int k = 1; k < 16; ++k) air += density.sample(start + (k / 16.0) * (c - start)) < 0.01f;
            score = hd * (0.25 + air / 15.0);
        }
        if (score > best) best = score, bolt.target = c;
    }
    if (glm::length(bolt.target - start) < 2.0 * p.segment_length_mean)  // a one-voxel cloud
        bolt.target = clamp_to(box, start + glm::dvec3(4.0 * p.segment_length_mean, 0.0, 0.0));
}

// The walk aims at points spaced kWaypointSegments segments along the straight line to the
// target, each displaced sideways by N(0, wander * spacing) — the channel's kilometre-scale
// bends. The last waypoint is the target itself.
std::vector<glm::dvec3> BoltBuilder::waypoints(core::Rng& rng) const {
    constexpr double kWaypointSegments = 4.0;
    const double direct = glm::length(bolt.target - start);
    const double spacing = kWaypointSegments * p.segment_length_mean;
    const int n = std::max(1, int(direct / spacing));
    const glm::dvec3 axis = toward(start, bolt.target);
    glm::dvec3 u, v;
    core::orthonormal_basis(axis, u, v);
    std::vector<glm::dvec3> out;
    for (int k = 1; k < n; ++k) {
        const double f = double(k) / n;
        const glm::dvec3 w =
            start + f * (bolt.target - start) + p.wander * spacing * (rng.normal() * u + rng.normal() * v);
        glm::dvec3 lo = box.lo + inset, hi = box.hi - inset;
        lo.z = std::max(lo.z, p.ground_height + p.segment_length_mean);
        out.push_back(glm::clamp(w, lo, glm::max(lo, hi)));
    }
    out.push_back(bolt.target);
    return out;
}

// The main channel: a walk of drawn segment lengths and turns toward the waypoints, mirrored
// at the domain's walls, until it reaches the ground (cloud-to-ground), its target, the
// segment cap or (intra-cloud, cloud-to-cloud) wanders too far.
void BoltBuilder::main_channel(core::Rng& rng, const std::vector<glm::dvec3>& waypoints) {
    const double ground = p.ground_height;
    const std::size_t cap = std::size_t(p.max_segments);
    const double direct = glm::length(bolt.target - start);
    std::size_t next_wp = 0;
    // A walk turning ~angle_mean per segment circles with radius ~ L / angle: an aim point is
    // "reached" within that radius or once passed along the line of flight, else the walk
    // would orbit it.
    const double reach =
        std::max(2.0 * p.segment_length_mean, p.segment_length_mean / std::max(p.angle_mean_deg * kDeg, 0.05));
    const glm::dvec3 line = bolt.target - start;
    const double bias_ramp = 3.0 * direct + 20.0 * p.segment_length_mean;  // beyond this path length: bias 1
    glm::dvec3 pos = start;
    glm::dvec3 d;
    {
        glm::dvec3 u, v;
        const glm::dvec3 t0 = toward(start, bolt.target);
        core::orthonormal_basis(t0, u, v);
        d = turn(t0, u, v, Walk::angle(rng, walk.theta_mean, walk.theta_sd), 2.0 * std::numbers::pi * rng.uniform());
    }
    double path = 0.0;
    glm::dvec3 side(0.0);  // sideways direction of the previous turn (zig-zag preference)
    for (std::size_t n = 0; n + 1 < cap; ++n) {
        const double len = walk.length(rng);
        if (n > 0) {
            const double bias = path > bias_ramp ? 1.0 : p.target_bias;
            // Move on once the current waypoint is near, or behind along the line of flight.
            while (next_wp + 1 < waypoints.size() &&
                   (glm::length(waypoints[next_wp] - pos) < reach || glm::dot(waypoints[next_wp] - pos, line) < 0.0))
                ++next_wp;
            walk.turn_toward(rng, pos, len, toward(pos, waypoints[next_wp]), bias, d, side);
        }
        // Walls: mirror the direction at each wall the step would cross (the ground is a wall
        // only for intra-cloud and cloud-to-cloud bolts).
        glm::dvec3 end = pos + len * d;
        bool reflected = false;
        for (int k = 0; k < 3; ++k) {
            const bool floor_is_wall = k < 2 || !cg;
            if (end[k] > box.hi[k] || (floor_is_wall && end[k] < box.lo[k])) d[k] = -d[k], reflected = true;
        }
        if (reflected) {
            ++bolt.reflections;
            end = pos + len * d;
            glm::dvec3 lo = box.lo;
            if (cg) lo.z = -1e300;
            end = glm::clamp(end, lo, box.hi);  // a box thinner than a segment
            if (!(glm::length(end - pos) > 0.0)) break;
            d = glm::normalize(end - pos);
        }
        Segment s;
        s.a = pos;
        s.intensity = p.intensity;
        s.path_start = path;
        s.parent = bolt.segments.empty() ? -1 : std::int32_t(bolt.segments.size() - 1);
        s.depth = 0;
        if (cg && end.z <= ground) {
            const double f = (pos.z - ground) / (pos.z - end.z);
            end = pos + f * (end - pos);
            end.z = ground;
            s.b = end;
            bolt.segments.push_back(s);
            bolt.reached_target = true;
            path += s.length();
            break;
        }
        s.b = end;
        bolt.segments.push_back(s);
        path += s.length();
        pos = end;
        if (!cg && (glm::length(bolt.target - pos) < std::min(reach, 0.25 * direct + p.segment_length_mean) ||
                    glm::dot(bolt.target - pos, line) <= 0.0)) {
            bolt.reached_target = true;
            break;
        }
        if (!cg && path > 2.0 * bias_ramp) break;  // wandered off: end the channel here
    }
    if (cg && !bolt.reached_target) close_to_ground(pos, path);
    bolt.main_count = bolt.segments.size();
    bolt.main_length = path;
}

// Segment cap reached above the ground: close with a straight leg down (documented).
void BoltBuilder::close_to_ground(const glm::dvec3& pos, double& path) {
    Segment s;
    s.a = pos;
    s.b = glm::dvec3(pos.x, pos.y, p.ground_height);
    s.intensity = p.intensity;
    s.path_start = path;
    s.parent = bolt.segments.empty() ? -1 : std::int32_t(bolt.segments.size() - 1);
    bolt.segments.push_back(s);
    path += s.length();
    bolt.reached_target = true;
    bolt.forced = true;
}

// Branches, breadth first (so a low segment cap keeps the big branches): each segment may
// spawn one with branch_probability, with a share of the length left below it; a branch
// walks toward its parent's drift and stops at its budget, where the main leader attaches
// (its path position main_length), or at the domain's walls and the ground.
void BoltBuilder::branches(std::uint64_t seed) {
    const std::size_t cap = std::size_t(p.max_segments);
    struct Request {
        std::int32_t parent;
        std::int32_t depth;
        glm::dvec3 origin, dir, drift;
        double intensity, path, budget;
    };
    std::deque<Request> queue;
    core::Rng decide(seed, 1);
    const glm::dvec3 main_drift = toward(start, bolt.target);
    auto consider_spawn = [&](std::size_t seg_index, std::int32_t depth, const glm::dvec3& drift, double remaining) {
        if (depth >= p.max_depth || !(p.branch_probability > 0.0)) return;
        if (decide.uniform() >= p.branch_probability) return;
        const Segment& s = bolt.segments[seg_index];
        const double budget = p.branch_length_fraction * remaining * (0.5 + decide.uniform());
        if (budget < 0.5 * p.segment_length_mean) return;
        const glm::dvec3 dir = glm::normalize(s.b - s.a);
        queue.push_back({std::int32_t(seg_index), depth + 1, s.b, dir, drift, s.intensity * p.branch_intensity_decay,
                         s.path_start + s.length(), budget});
    };
    for (std::size_t i = 0; i + 1 < bolt.main_count; ++i)
        consider_spawn(i, 0, main_drift, bolt.main_length - (bolt.segments[i].path_start + bolt.segments[i].length()));

    std::uint64_t branch_no = 0;
    while (!queue.empty() && bolt.segments.size() < cap) {
        const Request q = queue.front();
        queue.pop_front();
        core::Rng r(seed, 2 + branch_no++);
        glm::dvec3 u, v;
        core::orthonormal_basis(q.dir, u, v);
        glm::dvec3 dd = turn(q.dir, u, v, Walk::angle(r, p.branch_angle_mean_deg * kDeg, walk.theta_sd),
                             2.0 * std::numbers::pi * r.uniform());
        const glm::dvec3 drift = glm::normalize(dd + q.drift);
        glm::dvec3 bpos = q.origin;
        double travelled = 0.0, bpath = q.path;
        glm::dvec3 bside(0.0);
        std::int32_t parent = q.parent;
        for (bool first = true; bolt.segments.size() < cap; first = false) {
            double len = walk.length(r);
            if (!first) walk.turn_toward(r, bpos, len, drift, p.target_bias, dd, bside);
            bool stop = false;
            if (travelled + len >= q.budget) len = q.budget - travelled, stop = true;
            if (bpath + len >= bolt.main_length) len = bolt.main_length - bpath, stop = true;
            if (!(len > 1e-9)) break;
            glm::dvec3 delta = len * dd;
            const double f = exit_fraction(box, bpos, delta);
            if (f <= 1.0) {
                delta *= f;
                stop = true;
                ++bolt.clipped;
                if (!(glm::length(delta) > 1e-9)) break;
            }
            Segment s;
            s.a = bpos;
            s.b = bpos + delta;
            if (f <= 1.0) s.b = clamp_to(box, s.b);
            s.intensity = q.intensity;
            s.path_start = bpath;
            s.parent = parent;
            s.depth = q.depth;
            const double sl = s.length();
            bolt.segments.push_back(s);
            parent = std::int32_t(bolt.segments.size() - 1);
            travelled += sl;
            bpath += sl;
            bpos = s.b;
            if (stop) break;
            consider_spawn(bolt.segments.size() - 1, q.depth, drift, q.budget - travelled);
        }
    }
}

}  // namespace

Bolt BoltGenerator::generate_from(const glm::dvec3& start, std::uint64_t seed) const {
    FULGUR_ASSERT(domain_.contains(start), "generate_from: the start point must lie inside the domain");
    const BoltParams& p = p_;
    const Walk walk{p,
                    domain_,
                    *density_,
                    p.angle_mean_deg * kDeg,
                    p.angle_spread_deg * kDeg,
                    p.kind == Kind::IntraCloud ? 4 : 1,
                    std::max(0.5 * p.start_density_threshold, 1e-3)};
    Bolt bolt;
    bolt.kind = p.kind;
    bolt.seed = seed;
    bolt.start = start;
    BoltBuilder build{p, domain_, *density_, sampler_, walk, start, bolt};
    core::Rng rng(seed, 0);
    build.choose_target(rng);
    build.main_channel(rng, build.waypoints(rng));
    if (bolt.main_count > 0) build.branches(seed);
    return bolt;
}

}  // namespace fulgur::lightning
