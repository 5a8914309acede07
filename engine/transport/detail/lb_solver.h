// Internal: the lattice-Boltzmann problem, its two kernels and the stepping driver.
// Tests include this header to step a lattice, inspect densities and check energy.
//
// One step (both kernels): every site collides its arriving densities f (Theta f), adds
// its constant source emission, and streams the result to the neighbours; what streams
// out of an open face is counted as escaped, and every in-link of an open face receives
// its constant inflow for the next step. The state between steps is the "arriving"
// density f_q(x): what reached site x in direction q and is about to collide there.
// Energy in lattice units: sources and inflow are powers (W) injected per step.
#pragma once

#include "transport/detail/lb_collision.h"

#include <memory>
#include <span>
#include <vector>

namespace fulgur::transport::lb {

enum class Boundary { Open, Periodic };

struct Problem {
    core::Int3 dims{1, 1, 1};
    std::array<Boundary, 3> boundary{Boundary::Open, Boundary::Open, Boundary::Open};
    /// The z faces (low, high) of a slab that border another slab of a lattice decomposed over
    /// processes (make_slab_kernel): links crossing them are neither open nor periodic, the
    /// caller exchanges their densities with the neighbouring slab.
    std::array<bool, 2> halo_z{false, false};
    LbAbsorption absorption = LbAbsorption::Physical;
    double albedo = 1.0;
    DiscretePhase phase;
    /// Extinction probability per site for axis and diagonal arrivals (x fastest).
    std::vector<float> ext_axis, ext_diag;

    /// Constant inflow arriving at `site` in direction `dir` from outside an open face.
    struct Inflow {
        std::size_t site;
        int dir;
        float value;
    };
    std::vector<Inflow> inflow;

    /// Constant post-collision emission of a source site (own-voxel collision applied).
    struct Source {
        std::size_t site;
        std::array<float, kQ> out;
    };
    std::vector<Source> sources;

    double inflow_per_step = 0.0;           ///< sum of inflow values (double)
    double emission_per_step = 0.0;         ///< raw source power before the own-voxel collision
    double source_absorbed_per_step = 0.0;  ///< absorbed in the emitting voxels (physical model)

    std::size_t sites() const noexcept { return dims.volume(); }
    std::size_t index(int x, int y, int z) const noexcept {
        return std::size_t(x) + std::size_t(dims.x) * (std::size_t(y) + std::size_t(dims.y) * std::size_t(z));
    }
    /// A problem with uniform site coefficients and no sources.
    static Problem uniform(core::Int3 dims, const SiteCoefficients& c, const DiscretePhase& phase,
                           LbAbsorption absorption);
    /// Adds a source of raw emission e_q (W per step per direction, q = 1..18) at `site`,
    /// applying the own-voxel collision (docs: "Sources"); returns the own-voxel track
    /// sum_q (track of e_q) per direction, in m*W, for the fluence.
    std::array<double, kQ> add_source(std::size_t site, const std::array<double, kQ>& emission,
                                      const SiteCoefficients& c);
};

class Kernel {
public:
    virtual ~Kernel() = default;
    /// One collide + stream step.
    virtual void step() = 0;
    /// Absorbed (physical model; rest-direction absorption of the conservative model is
    /// stored, not absorbed) and escaped density of the last step, double sums.
    virtual double last_absorbed() const = 0;
    virtual double last_escaped() const = 0;
    /// Sum of all arriving densities (all sites, all directions), double: a full pass.
    virtual double stored() const = 0;
    /// The same total as accumulated by the last step itself (collided output per row,
    /// minus outflow, plus inflow): what the steady-state test watches. It follows the
    /// lattice's actual float32 content, including rounding drift the bookkeeping misses.
    virtual double last_total() const = 0;
    /// Arriving density at a site (index as Problem::index) in direction q.
    virtual float arriving(std::size_t site, int q) const = 0;
    /// Sets an arriving density; only before the first step.
    virtual void set_arriving(std::size_t site, int q, float v) = 0;
    /// What last_absorbed(), last_escaped() and last_total() return after a step.
    struct StepResult {
        double absorbed = 0.0, escaped = 0.0, total = 0.0;
    };
    /// Two steps, with the results of each; afterwards the last_*() accessors report the
    /// second. The fast kernel runs both in one sweep over the lattice where it can (from
    /// an even step, no periodic faces): the same result, about half the memory traffic.
    virtual void two_steps(StepResult& first, StepResult& second) {
        step();
        first = {last_absorbed(), last_escaped(), last_total()};
        step();
        second = {last_absorbed(), last_escaped(), last_total()};
    }
    /// A kernel holding only part of the lattice (one process's slab of a decomposed lattice,
    /// whose arriving() answers for its own sites): every site's arriving densities, index
    /// site * kQ + q, the same on every process (a collective call). Empty for a kernel that
    /// holds the whole lattice.
    virtual std::vector<float> gather_all() const { return {}; }
    int steps() const noexcept { return steps_; }

protected:
    int steps_ = 0;
};

/// The paper's Appendix B: AoS nodes, dense 19x19 collision per site, separate streaming
/// pass into a second lattice (single thread, float32).
std::unique_ptr<Kernel> make_naive_kernel(const Problem& p);
/// The fast kernel: SoA float32 with a one-site ghost layer, in-place AA-pattern streaming,
/// factored collision, OpenMP over rows (core::thread_count()).
std::unique_ptr<Kernel> make_fast_kernel(const Problem& p);
std::unique_ptr<Kernel> make_kernel(const Problem& p, LbKernel kind);

/// The fast kernel on one z-slab of a lattice decomposed over processes: `p` is the slab (open
/// faces, and halo_z on the z faces another slab follows). Its
/// step is done in parts so that the caller exchanges the halo links between them and
/// overlaps the exchange with the interior planes, for each half (even, then odd):
///   update_planes(odd, 0, 1), update_planes(odd, nz - 1, nz)   the two face planes
///   pack(odd, side) -> send; receive -> ...                    while
///   update_planes(odd, 1, nz - 1)                              the interior planes
///   ... -> unpack(odd, side)                                   before the next half
/// then add_rows() chained over the slabs in z order and end_step() with the lattice's
/// figures. Every site computes exactly what it does in the undivided fast kernel, and the
/// chained sums add the same rows in the same order, so the lattice is bit-identical.
class SlabKernel : public Kernel {
public:
    virtual void update_planes(bool odd, int z0, int z1) = 0;
    /// The halo values leaving through face `side` (0: z = 0, 1: z = nz - 1) after a half,
    /// in the order the neighbour's unpack(odd, other side) takes them.
    virtual void pack(bool odd, int side, std::vector<float>& out) const = 0;
    virtual void unpack(bool odd, int side, std::span<const float> in) = 0;
    /// Values crossing a face in one direction per half.
    virtual std::size_t halo_size() const = 0;
    struct Sums {
        double absorbed = 0.0, total = 0.0, escaped = 0.0;
    };
    /// `from` continued over this slab's per-row sums of the last half, in row order.
    virtual Sums add_rows(Sums from) const = 0;
    /// `from` continued over this slab's constant inflow, in the undivided kernel's order.
    virtual double add_inflow(double from) const = 0;
    /// Ends a step with the lattice's figures (absorbed includes the sources' own).
    virtual void end_step(double absorbed, double escaped, double total) = 0;
};
std::unique_ptr<SlabKernel> make_slab_kernel(const Problem& p);

/// Steps a kernel with energy bookkeeping (double) and the steady-state test.
class Simulation {
public:
    Simulation(const Problem& p, LbKernel kind);
    /// With a kernel made elsewhere for `p` (a slab of a decomposed lattice: the kernel steps
    /// its part, the figures are the whole lattice's).
    Simulation(const Problem& p, std::unique_ptr<Kernel> kernel);
    Simulation(const Simulation&) = delete;  // the kernel refers to problem_
    Simulation& operator=(const Simulation&) = delete;
    void step();
    /// Two steps (Kernel::two_steps: one sweep in the fast kernel); the kernel's total after
    /// the first goes to *first_total if given.
    void step_two(double* first_total = nullptr);
    /// Steps until the relative change of the total density per step, and the change still
    /// to come extrapolated from the ratio of successive increments, are both below
    /// `tolerance` (tested after even steps, over two steps), or until the change is below
    /// the float32 noise floor, or `max_steps` (rounded up to even) is reached.
    bool run(double tolerance, int max_steps, std::vector<double>* history = nullptr);

    const Kernel& kernel() const noexcept { return *kernel_; }
    Kernel& kernel() noexcept { return *kernel_; }
    int steps() const noexcept { return kernel_->steps(); }
    double injected_total() const noexcept { return injected_; }
    double absorbed_total() const noexcept { return absorbed_; }
    double escaped_total() const noexcept { return escaped_; }
    /// Total density from the bookkeeping (injected - absorbed - escaped); kernel().stored()
    /// measures it independently.
    double balance() const noexcept { return injected_ - absorbed_ - escaped_; }
    double last_change() const noexcept { return last_change_; }
    /// Relative change still to come, extrapolated from the ratio of successive increments.
    double estimated_remaining() const noexcept { return estimated_remaining_; }
    bool converged() const noexcept { return converged_; }
    const Problem& problem() const noexcept { return problem_; }

private:
    Problem problem_;
    std::unique_ptr<Kernel> kernel_;
    double injected_ = 0.0, absorbed_ = 0.0, escaped_ = 0.0;
    double last_change_ = 1.0, estimated_remaining_ = 1.0;
    bool converged_ = false;
};

/// solve_lattice_boltzmann() with a choice of boundaries (periodic axes have no inflow).
LbResult solve(const LightingMedium& medium, const LbSources& sources, std::span<const glm::dvec3> directions,
               const LbSettings& settings, std::array<Boundary, 3> boundary);

}  // namespace fulgur::transport::lb
