// fulgur::distributed — one lattice-Boltzmann lattice decomposed in z-slabs over the ranks of
// a Session (docs/distributed.md): each rank steps its slab with the fast kernel, exchanging
// the streaming links that cross a slab face with its neighbours (non-blocking, while it
// updates its interior planes) and chaining the per-row sums of the convergence test in the
// undivided lattice's order, so the lattice is bit-identical to the single-process one.
// Internal (not installed): it speaks the transport module's internal lattice types
// (transport/detail/lb_solver.h), for the lattice's own drivers, benchmarks and tests.
#pragma once

#include "distributed/distributed.h"
#include "transport/detail/lb_solver.h"

#include <memory>
#include <vector>

namespace fulgur::distributed {

/// This rank's z-slab of `lattice` (open faces; planes nz * r / p .. nz * (r + 1) / p, at least
/// 2 per rank: core::Error otherwise), as a kernel that lb::Simulation steps on every rank at
/// once. Its figures (last_total, absorbed, escaped) are the whole lattice's, the same on every
/// rank. arriving() and set_arriving() take the lattice's site indices and answer for the
/// rank's own sites (set_arriving ignores the others; arriving asserts on them).
class LatticeSlab final : public transport::lb::Kernel {
public:
    LatticeSlab(const Session& session, const transport::lb::Problem& lattice);
    ~LatticeSlab() override;

    void step() override;
    double last_absorbed() const override { return absorbed_; }
    double last_escaped() const override { return escaped_; }
    double last_total() const override { return total_; }
    /// Sum over every rank (MPI_Allreduce: not in the undivided kernel's order).
    double stored() const override;
    float arriving(std::size_t site, int q) const override;
    void set_arriving(std::size_t site, int q, float v) override;

    int z_begin() const noexcept { return z0_; }
    int z_end() const noexcept { return z1_; }
    /// Floats sent to each neighbour per step (both halves).
    std::size_t halo_floats_per_step() const noexcept { return 2 * halo_; }
    /// Every site's arriving densities (index site * 19 + q), on rank 0 (empty on the others).
    std::vector<float> gather() const;
    /// The same on every rank (MPI_Allgatherv): what lb::solve reads out.
    std::vector<float> gather_all() const override;

private:
    const Session& session_;
    transport::lb::Problem slab_;
    std::unique_ptr<transport::lb::SlabKernel> kernel_;
    std::size_t plane_ = 0, halo_ = 0;
    int z0_ = 0, z1_ = 0;
    double inflow_ = 0.0, source_absorbed_ = 0.0;
    double absorbed_ = 0.0, escaped_ = 0.0, total_ = 0.0;
    std::vector<float> send_[2], recv_[2];
};

}  // namespace fulgur::distributed
