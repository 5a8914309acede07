// fulgur::lightning — lightning bolts and the virtual-light weights they drive
// (Dobashi et al. 2007, sections 3, 4 and 7; bolt shapes after Reed & Wyvill 1994).
//
// Per frame the run time does:
//
//   Storm::point_sources(t)  ──► point sources (empty: no flash, skip the frame's lighting)
//   Splatter::splat(sources) ──► LightWeights: e_l for every virtual light l of a
//                                basis::VirtualLightGrid, plus the ascending list of the
//                                lights with e_l != 0 (Dobashi Eq. 6)
//
// The pieces, each usable on its own (docs/lightning.md describes each):
//  * BoltGenerator: the Reed-Wyvill channel, a walk of straight segments with branches,
//    deterministic per seed; only the turn azimuth is biased toward the target.
//  * FlashProfile / flash_state: the temporal shape of one strike (leader, return stroke,
//    decay, restrikes).
//  * Storm: strike scheduling (Poisson per seed, or on demand) and the point sources at t.
//  * Splatter: trilinear splatting onto the virtual-light grid, conserving energy exactly.
//
// Units: metres, seconds; segment intensity is radiant intensity per metre of channel
// (W/sr/m); a point source's intensity is radiant intensity (W/sr), the unit of a virtual
// light (a unit virtual light is 1 W/sr, transport.h). Coordinates: z up.
// Docs: docs/lightning.md.
#pragma once

#include "basis/virtual_lights.h"
#include "core/core.h"
#include "transport/sources.h"

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace fulgur::lightning {

// ---------------------------------------------------------------------------------------
// Parameters (scene section "lightning"; docs/lightning.md lists defaults and sources)

enum class Kind { CloudToGround, IntraCloud, CloudToCloud };

/// "cloud_to_ground", "intra_cloud", "cloud_to_cloud" (the scene-file spelling).
std::string_view kind_name(Kind k) noexcept;

/// Shape of a bolt.
struct BoltParams {
    Kind kind = Kind::CloudToGround;
    double angle_mean_deg = 16.0;          ///< mean turn between successive segments (Reed-Wyvill: ~16 deg)
    double angle_spread_deg = 10.0;        ///< standard deviation of the turn angle (deg)
    double segment_length_mean = 200.0;    ///< m
    double segment_length_spread = 80.0;   ///< m, standard deviation; lengths truncated to [0.2, 3] x mean
    double target_bias = 0.8;              ///< [0,1]: 0 = unbiased turn azimuth, 1 = always turn toward the aim point
    double zigzag = 1.0;                   ///< [0,4]: preference for turning back the other way (0 = none)
    double wander = 0.5;                   ///< sideways spread of the aim points (every 4 segments), x their spacing
    double branch_probability = 0.2;       ///< chance per segment to sprout a branch
    double branch_angle_mean_deg = 35.0;   ///< first turn of a branch away from its parent (deg)
    double branch_length_fraction = 0.3;   ///< mean branch length / parent channel length still to go
    double branch_intensity_decay = 0.4;   ///< a depth-d channel carries intensity * decay^d
    int max_depth = 3;                     ///< deepest branch level (0 = main channel only)
    double intensity = 1.0e5;              ///< main channel at the return-stroke peak, W/sr/m
    double start_density_threshold = 0.3;  ///< start points lie in voxels whose density exceeds this
    double ground_height = 0.0;            ///< z of the ground plane (m); cloud-to-ground bolts end on it
    int max_segments = 20000;              ///< hard cap on segments per bolt (guards absurd parameters)
};

/// Temporal profile of a strike. Defaults follow measured lightning (Uman 1987; Rakov &
/// Uman 2003): stepped leader ~2e5 m/s (tens of ms for a few km), dart leader ~1e7 m/s,
/// 3-4 strokes per flash, ~50-60 ms between strokes, subsequent strokes dimmer.
struct TimingParams {
    double leader_speed = 2.0e5;       ///< stepped-leader front speed along the channel, m/s
    double leader_brightness = 0.03;   ///< leader glow relative to the first return-stroke peak
    double rise_time = 1.0e-4;         ///< return-stroke rise (linear), s
    double decay_time = 0.012;         ///< e-folding time of a stroke's glow, s
    double restrikes = 2.0;            ///< mean number of restrikes per strike (Poisson)
    int restrikes_max = 8;             ///< cap on the drawn number
    double restrike_interval = 0.05;   ///< median time between stroke onsets, s (log-normal, sigma 0.4)
    double restrike_brightness = 0.5;  ///< restrike peak relative to the first stroke
    double dart_leader_speed = 1.0e7;  ///< m/s; the dart leader re-lights the main channel top-down
    double dark_threshold = 1.0e-3;    ///< a stroke is over when its glow falls below this (relative)
};

/// When strikes happen.
struct ScheduleParams {
    double strike_rate = 0.2;   ///< strikes per second (Poisson); 0 = on demand only
    double first_strike = 0.5;  ///< s: time of the first scheduled strike (later ones are Poisson)
};

struct LightningParams {
    std::uint64_t seed = 1;
    BoltParams bolt;
    TimingParams timing;
    ScheduleParams schedule;
};

/// Checks every field (finite, in range, consistent); throws core::Error naming
/// "<where>.<field>" and the allowed range. The scene parser applies the same ranges.
void validate(const LightningParams& p, std::string_view where = "lightning");

// ---------------------------------------------------------------------------------------
// Bolts

/// Axis-aligned box (m).
struct Box {
    glm::dvec3 lo{0.0}, hi{0.0};
    bool contains(const glm::dvec3& p) const noexcept {
        return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
    }
};

struct Segment {
    glm::dvec3 a{0.0}, b{0.0};  ///< endpoints (m); a is nearer the start point along the channel
    double intensity = 0.0;     ///< W/sr/m at the first return-stroke peak
    double path_start = 0.0;    ///< channel length from the bolt's start point to a (m)
    std::int32_t parent = -1;   ///< segment this one continues or branches off; -1 for the first
    std::int32_t depth = 0;     ///< 0 = main channel, d = branch of depth d
    double length() const noexcept;
};

struct Bolt {
    Kind kind = Kind::CloudToGround;
    std::uint64_t seed = 0;
    glm::dvec3 start{0.0}, target{0.0};
    /// Main channel first, in order from the start point ([0, main_count)); branches after.
    std::vector<Segment> segments;
    std::size_t main_count = 0;
    double main_length = 0.0;     ///< path length of the main channel (m)
    bool reached_target = false;  ///< CG: ended on the ground; IC/CC: came within a segment of the target
    std::size_t reflections = 0;  ///< main-channel steps mirrored at the domain's walls
    std::size_t clipped = 0;      ///< branches stopped at the domain's walls
    bool forced = false;          ///< CG fallback: segment cap reached, closed by a straight leg to the ground
    double total_length() const noexcept;
};

/// Picks start points: uniform over the voxels whose density exceeds the threshold and whose
/// centre is above `min_height`, jittered inside the voxel. Throws core::Error
/// ("lightning.start_density_threshold") if no voxel qualifies, naming the maximum density.
class StartSampler {
public:
    StartSampler(const core::Grid3<float>& density, double threshold, double min_height);
    glm::dvec3 sample(core::Rng& rng) const;
    std::size_t candidates() const noexcept { return cells_.size(); }

private:
    core::GridGeometry geom_;
    std::vector<std::uint32_t> cells_;
};

/// Generates bolts in a cloud. Keeps a reference to `density`, which must outlive it.
/// The domain defaults to the density grid's box with its floor moved to the ground; a
/// caller's box has its floor raised to the ground (a ground below its floor is an error).
/// The main channel mirrors at the walls (counted in Bolt::reflections), branches stop at
/// them (Bolt::clipped). Throws core::Error for invalid parameters, a ground within a
/// segment of the domain's top, or a cloud with no voxel above the start threshold.
/// Not thread-safe to construct concurrently with edits of `density`; generate() is const
/// and may run on several threads.
class BoltGenerator {
public:
    BoltGenerator(const BoltParams& p, const core::Grid3<float>& density, std::optional<Box> domain = {});
    /// A bolt from a start point drawn from the cloud. Same seed -> bit-identical bolt.
    Bolt generate(std::uint64_t seed) const;
    /// A bolt from a given start point (must lie inside the domain).
    Bolt generate_from(const glm::dvec3& start, std::uint64_t seed) const;
    const Box& domain() const noexcept { return domain_; }
    const BoltParams& params() const noexcept { return p_; }

private:
    BoltParams p_;
    const core::Grid3<float>* density_;
    Box domain_;
    StartSampler sampler_;
};

// ---------------------------------------------------------------------------------------
// Flash timing

/// Times relative to the strike's start (the stepped leader leaves the start point at 0).
/// Stroke k has onset stroke_onset[k] and relative peak stroke_peak[k]; stroke 0 is the
/// return stroke at leader_duration (peak 1); strokes k >= 1 are restrikes, each preceded by
/// a dart leader that re-lights the main channel from the start point in dart_duration.
struct FlashProfile {
    double leader_duration = 0.0;  ///< s
    double dart_duration = 0.0;    ///< s
    std::vector<double> stroke_onset;
    std::vector<double> stroke_peak;
    std::vector<double> stroke_end;  ///< after this the stroke's glow is exactly zero
    double duration = 0.0;           ///< the flash is dark (exactly zero) for t >= duration
};

/// Draws the restrikes (count and intervals) from `seed`; the leader's duration comes from
/// the bolt's main-channel length.
FlashProfile make_flash_profile(const Bolt& bolt, const TimingParams& p, std::uint64_t seed);

/// The flash at time t after the strike's start. A segment's glow per metre is
///   intensity * (depth == 0 ? main_glow : branch_glow)       over its whole length, plus
///   intensity * leader_glow over the part with path position < leader_front
///     (only main-channel segments when leader_main_only: a dart leader).
struct FlashState {
    double main_glow = 0.0;
    double branch_glow = 0.0;  ///< branches glow with the first return stroke only
    double leader_glow = 0.0;
    double leader_front = 0.0;  ///< m along the channel
    bool leader_main_only = false;
    bool active() const noexcept {
        return main_glow > 0.0 || branch_glow > 0.0 || (leader_glow > 0.0 && leader_front > 0.0);
    }
};

FlashState flash_state(const FlashProfile& f, const TimingParams& p, double t) noexcept;

/// The two parts of a flash whose light is made differently: the leaders (stepped and dart,
/// creeping down a channel before each stroke) and the strokes (the return strokes lighting
/// the main channel and, with the first, its branches). Each part is a FlashState with the
/// other's glow zero, so lit_segments of the two parts together give the whole flash.
struct FlashParts {
    FlashState leaders;
    FlashState strokes;
};
FlashParts split_leaders(const FlashState& s) noexcept;

/// A lit stretch of channel with uniform brightness: what the renderer draws and what point
/// sources sample.
struct LitSegment {
    glm::dvec3 a{0.0}, b{0.0};
    double intensity = 0.0;  ///< W/sr/m at this instant
    std::int32_t depth = 0;
};

/// Appends the lit stretches of `bolt` in state `s` (none when dark).
void lit_segments(const Bolt& bolt, const FlashState& s, std::vector<LitSegment>& out);

// ---------------------------------------------------------------------------------------
// Point sources and splatting

/// Samples lit stretches with point sources no farther apart than `max_spacing` (each
/// stretch of length len gets n = ceil(len / max_spacing) sources at the midpoints of n equal
/// pieces, each carrying intensity * len / n), so the total intensity sum_q L_q equals
/// sum intensity * len whatever the spacing. Returns that total (compensated sum).
double append_point_sources(std::span<const LitSegment> lit, double max_spacing,
                            std::vector<transport::PointSource>& out);

/// Virtual-light intensities e_l for one frame.
struct LightWeights {
    std::vector<double> e;              ///< one per light of the grid, l = i + nx*(j + ny*k)
    std::vector<std::uint32_t> active;  ///< lights with e_l != 0, ascending
    double total = 0.0;                 ///< sum of the splatted L_q (compensated)
    std::size_t sources = 0;            ///< sources splatted (clamped ones included)
    std::size_t clamped = 0;            ///< sources outside the grid's box, moved onto it
    std::size_t rejected = 0;           ///< non-finite position or intensity: skipped
    std::vector<std::uint8_t> touched;  ///< internal: marks lights listed in `active`
    bool empty() const noexcept { return active.empty(); }
};

/// Trilinear splatting (Dobashi Eq. 6) onto a rectilinear virtual-light grid.
/// Per axis, the cell holding a coordinate is found by a precomputed uniform lookup table
/// (bin width = the axis's smallest spacing, so at most one step of correction).
class Splatter {
public:
    /// Throws core::Error ("virtual-light grid") if an axis is empty, non-finite or not
    /// strictly ascending.
    explicit Splatter(const basis::VirtualLightGrid& grid);

    /// Zeroes `out` (sparsely, touching only the previous frame's active lights) and splats.
    void splat(std::span<const transport::PointSource> sources, LightWeights& out) const;
    /// Adds to `out` without zeroing it (several bolts into one frame). `out` must come from
    /// splat()/reset() on this grid.
    void accumulate(std::span<const transport::PointSource> sources, LightWeights& out) const;
    /// Sizes `out` for this grid and zeroes it sparsely.
    void reset(LightWeights& out) const;
    /// Reference implementation with a binary search per axis (the benchmark's baseline and
    /// the tests' oracle); same result as accumulate().
    void accumulate_binary_search(std::span<const transport::PointSource> sources, LightWeights& out) const;

    std::size_t light_count() const noexcept { return count_; }
    /// Smallest distance between adjacent nodes on any axis.
    double min_spacing() const noexcept { return min_spacing_; }
    /// Point-source spacing used by Storm: half the grid's smallest spacing. Chosen globally
    /// (not per cell): on a Dobashi grid the horizontal spacing h_usr is the smallest
    /// everywhere, so a local choice would give the same spacing at extra cost.
    double source_spacing() const noexcept { return 0.5 * min_spacing_; }

    struct Axis {
        std::vector<double> nodes;
        std::vector<std::uint32_t> lut;  ///< bin -> cell index
        double inv_bin = 0.0;
        /// Cell i (nodes[i] <= v <= nodes[i+1]) and fraction f in [0,1]; v already clamped.
        void locate(double v, std::uint32_t& i, double& f) const noexcept;
        void locate_bsearch(double v, std::uint32_t& i, double& f) const noexcept;
    };

private:
    template <bool kLut>
    void accumulate_impl(std::span<const transport::PointSource> sources, LightWeights& out) const;
    Axis ax_[3];
    std::size_t count_ = 0;
    double min_spacing_ = 0.0;
    Box box_;
};

// ---------------------------------------------------------------------------------------
// Strikes over time

struct Strike {
    double time = 0.0;  ///< s: the stepped leader leaves the start point
    std::uint64_t seed = 0;
    FlashProfile profile;
    double end() const noexcept { return time + profile.duration; }
};

/// A storm: bolts scheduled over time from one seed. Scheduled strikes form a Poisson
/// process (the k-th inter-arrival time and the k-th strike's seed are derived from the
/// storm seed and k only), so any time t can be queried in any order with the same answer.
/// Bolts are generated when their strike is scheduled and dropped once it is over (and
/// regenerated bit-identically if an earlier time is queried again). Scheduling costs one
/// bolt generation per strike up to the queried time (~20-40 us each). Keeps a reference
/// to `density`.
class Storm {
public:
    Storm(const LightningParams& p, const core::Grid3<float>& density, std::optional<Box> domain = {});

    /// Schedules a strike starting at time t (on demand). Without a seed the m-th on-demand
    /// strike uses a seed derived from the storm seed and m. Returns the strike's index.
    std::size_t strike_at(double t, std::optional<std::uint64_t> seed = {});

    /// Indices of the strikes whose flash is not dark at t, ascending by start time. Cost: a
    /// binary search plus the strikes overlapping t (and scheduling strikes up to t). The
    /// span is valid until the next call. Storm is not thread-safe.
    std::span<const std::size_t> active(double t);
    /// Indices of the strikes starting in [t0, t1), ascending by start time, scheduling
    /// strikes up to t1 (the run time solves upcoming strikes ahead of their frames).
    std::vector<std::size_t> starting(double t0, double t1);
    /// True if any strike glows at t (the run time skips reconstruction when false).
    bool any_active(double t) { return !active(t).empty(); }

    /// Point sources of every active strike at t with the given spacing (see Splatter::
    /// source_spacing()), appended to `out` after clearing it. Returns false (out empty)
    /// when no strike glows at t.
    bool point_sources(double t, double max_spacing, std::vector<transport::PointSource>& out);
    /// Lit stretches of every active strike at t (for drawing), appended after clearing.
    bool lit(double t, std::vector<LitSegment>& out);

    const Strike& strike(std::size_t i) const { return strikes_[i].strike; }
    std::size_t strike_count() const noexcept { return strikes_.size(); }
    /// The strike's bolt (generated if needed).
    const Bolt& bolt(std::size_t i);
    const BoltGenerator& generator() const noexcept { return gen_; }
    const LightningParams& params() const noexcept { return p_; }

private:
    struct Entry {
        Strike strike;
        std::unique_ptr<Bolt> bolt;
    };
    std::size_t add(double t, std::uint64_t seed);
    void schedule_until(double t);

    LightningParams p_;
    BoltGenerator gen_;
    std::vector<Entry> strikes_;
    std::vector<std::size_t> by_time_;  ///< strike indices sorted by start time
    std::vector<std::size_t> live_;     ///< strikes currently holding their bolt
    double max_duration_ = 0.0;
    std::uint64_t scheduled_ = 0;  ///< Poisson strikes drawn so far
    double next_arrival_ = 0.0;    ///< start time of Poisson strike number scheduled_
    core::Rng arrivals_;
    std::uint64_t on_demand_ = 0;
    double latest_query_ = -1e300;
    std::vector<std::size_t> active_;
};

// ---------------------------------------------------------------------------------------
// Visual check

/// Draws lit stretches in a side view (x horizontal, z up) over the density's projection
/// (mean along y) into an 8-bit RGB image of `width` x height, where height follows the
/// view box's aspect ratio. Line width and brightness grow with intensity relative to
/// `reference` (W/sr/m; 0 = the brightest stretch drawn), additive glow. `view` is the
/// region shown (x and z used). Returns the pixels, rows top to bottom.
std::vector<std::uint8_t> draw_side_view(std::span<const LitSegment> lit, const core::Grid3<float>* density,
                                         const Box& view, int width, int& height, double reference = 0.0);

}  // namespace fulgur::lightning
