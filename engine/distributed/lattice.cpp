// The lattice in z-slabs over the ranks (lattice.h). A step is two halves of the fast kernel's
// AA pattern, each: the two face planes, then the halo links they produced sent to the
// neighbours (MPI_Isend / MPI_Irecv) while the interior planes update, then the received
// links written into place before the next half needs them (the even half fills the ghost
// planes the odd half reads; the odd half's outflow lands in the neighbour's face plane,
// which its next even half reads). The per-row sums go from rank 0 up the chain of ranks and
// the last one broadcasts the totals: the undivided kernel's sums, bit for bit, at the cost of
// one latency per rank per step.
#include "distributed/detail/lattice.h"

#ifdef FULGUR_HAVE_MPI
#include "distributed/detail/mpi.h"
#endif

namespace fulgur::distributed {

using transport::lb::kQ;
using transport::lb::SlabKernel;

#ifdef FULGUR_HAVE_MPI
namespace {
constexpr int kTagHalo = 10, kTagSums = 11;
}  // namespace
#endif

LatticeSlab::LatticeSlab(const Session& session, const transport::lb::Problem& lattice) : session_(session) {
    using transport::lb::Boundary;
    FULGUR_ASSERT(lattice.boundary[0] == Boundary::Open && lattice.boundary[1] == Boundary::Open &&
                      lattice.boundary[2] == Boundary::Open && !lattice.halo_z[0] && !lattice.halo_z[1],
                  "LatticeSlab: a lattice with open faces");
    const int p = session.size(), r = session.rank(), nz = lattice.dims.z;
    z0_ = int(std::int64_t(nz) * r / p);
    z1_ = int(std::int64_t(nz) * (r + 1) / p);
    if (z1_ - z0_ < 2)
        throw core::Error("lattice", "a " + std::to_string(nz) + "-plane lattice over " + std::to_string(p) +
                                         " ranks leaves rank " + std::to_string(r) + " " + std::to_string(z1_ - z0_) +
                                         " plane(s); each needs at least 2 (fewer ranks or a deeper lattice)");
    plane_ = std::size_t(lattice.dims.x) * std::size_t(lattice.dims.y);
    const std::size_t begin = std::size_t(z0_) * plane_, end = std::size_t(z1_) * plane_;
    slab_.dims = {lattice.dims.x, lattice.dims.y, z1_ - z0_};
    slab_.halo_z = {r > 0, r < p - 1};
    slab_.absorption = lattice.absorption;
    slab_.albedo = lattice.albedo;
    slab_.phase = lattice.phase;
    slab_.ext_axis.assign(lattice.ext_axis.begin() + std::ptrdiff_t(begin),
                          lattice.ext_axis.begin() + std::ptrdiff_t(end));
    slab_.ext_diag.assign(lattice.ext_diag.begin() + std::ptrdiff_t(begin),
                          lattice.ext_diag.begin() + std::ptrdiff_t(end));
    for (const auto& in : lattice.inflow)
        if (in.site >= begin && in.site < end) slab_.inflow.push_back({in.site - begin, in.dir, in.value});
    for (const auto& s : lattice.sources)
        if (s.site >= begin && s.site < end) slab_.sources.push_back({s.site - begin, s.out});
    kernel_ = transport::lb::make_slab_kernel(slab_);
    halo_ = kernel_->halo_size();
    source_absorbed_ = lattice.source_absorbed_per_step;

    // The constant inflow's total, chained in z order as the undivided kernel adds it.
    double inflow = 0.0;
#ifdef FULGUR_HAVE_MPI
    if (r > 0)
        detail::check(MPI_Recv(&inflow, 1, MPI_DOUBLE, r - 1, kTagSums, MPI_COMM_WORLD, MPI_STATUS_IGNORE), "MPI_Recv");
    inflow = kernel_->add_inflow(inflow);
    if (r < p - 1) detail::check(MPI_Send(&inflow, 1, MPI_DOUBLE, r + 1, kTagSums, MPI_COMM_WORLD), "MPI_Send");
    if (p > 1) detail::check(MPI_Bcast(&inflow, 1, MPI_DOUBLE, p - 1, MPI_COMM_WORLD), "MPI_Bcast");
#else
    inflow = kernel_->add_inflow(inflow);
#endif
    inflow_ = inflow;
    total_ = inflow_;  // the first inflow is in place at t = 0
}

LatticeSlab::~LatticeSlab() = default;

void LatticeSlab::step() {
    const bool odd = steps_ % 2 != 0;
    const int nz = slab_.dims.z;
    SlabKernel& k = *kernel_;
    k.update_planes(odd, 0, 1);
    k.update_planes(odd, nz - 1, nz);
    SlabKernel::Sums sums;
#ifdef FULGUR_HAVE_MPI
    const int r = session_.rank(), p = session_.size();
    MPI_Request req[4];
    int nreq = 0;
    for (int side = 0; side < 2; ++side) {
        if (!slab_.halo_z[std::size_t(side)]) continue;
        const int peer = side == 0 ? r - 1 : r + 1;
        recv_[side].resize(halo_);
        detail::check(
            MPI_Irecv(recv_[side].data(), int(halo_), MPI_FLOAT, peer, kTagHalo, MPI_COMM_WORLD, &req[nreq++]),
            "MPI_Irecv");
        k.pack(odd, side, send_[side]);
        detail::check(
            MPI_Isend(send_[side].data(), int(halo_), MPI_FLOAT, peer, kTagHalo, MPI_COMM_WORLD, &req[nreq++]),
            "MPI_Isend");
    }
    k.update_planes(odd, 1, nz - 1);  // the interior, while the halo travels
    detail::check(MPI_Waitall(nreq, req, MPI_STATUSES_IGNORE), "MPI_Waitall");
    for (int side = 0; side < 2; ++side)
        if (slab_.halo_z[std::size_t(side)]) k.unpack(odd, side, recv_[side]);
    if (r > 0)
        detail::check(MPI_Recv(&sums, 3, MPI_DOUBLE, r - 1, kTagSums, MPI_COMM_WORLD, MPI_STATUS_IGNORE), "MPI_Recv");
    sums = k.add_rows(sums);
    if (r < p - 1) detail::check(MPI_Send(&sums, 3, MPI_DOUBLE, r + 1, kTagSums, MPI_COMM_WORLD), "MPI_Send");
    if (p > 1) detail::check(MPI_Bcast(&sums, 3, MPI_DOUBLE, p - 1, MPI_COMM_WORLD), "MPI_Bcast");
#else
    k.update_planes(odd, 1, nz - 1);
    sums = k.add_rows(sums);
#endif
    // As the undivided kernel's finish_step.
    absorbed_ = sums.absorbed + source_absorbed_;
    escaped_ = sums.escaped;
    total_ = sums.total - escaped_ + inflow_;
    k.end_step(absorbed_, escaped_, total_);
    ++steps_;
}

double LatticeSlab::stored() const {
    double s = kernel_->stored();
#ifdef FULGUR_HAVE_MPI
    detail::check(MPI_Allreduce(MPI_IN_PLACE, &s, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD), "MPI_Allreduce");
#endif
    return s;
}

float LatticeSlab::arriving(std::size_t site, int q) const {
    const std::size_t begin = std::size_t(z0_) * plane_, end = std::size_t(z1_) * plane_;
    FULGUR_ASSERT(site >= begin && site < end, "LatticeSlab::arriving: a site of another rank's slab");
    return kernel_->arriving(site - begin, q);
}

void LatticeSlab::set_arriving(std::size_t site, int q, float v) {
    const std::size_t begin = std::size_t(z0_) * plane_, end = std::size_t(z1_) * plane_;
    if (site >= begin && site < end) kernel_->set_arriving(site - begin, q, v);
}

namespace {

// This rank's sites' arriving densities, index (site - first site of the slab) * kQ + q.
std::vector<float> own_sites(const SlabKernel& k, std::size_t sites) {
    std::vector<float> mine(sites * kQ);
    for (std::size_t s = 0; s < sites; ++s)
        for (int q = 0; q < kQ; ++q) mine[s * kQ + std::size_t(q)] = k.arriving(s, q);
    return mine;
}

#ifdef FULGUR_HAVE_MPI
// Every rank's slab in rank order (the slabs are consecutive runs of sites, so rank order is
// site order), on rank 0 only or on every rank.
std::vector<float> gather_slabs(const std::vector<float>& mine, int ranks, bool root, bool everyone) {
    std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks));
    FULGUR_ASSERT(mine.size() <= std::size_t(INT_MAX), "LatticeSlab: a slab larger than 2^31 floats");
    const int n = int(mine.size());
    if (everyone)
        detail::check(MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Allgather");
    else
        detail::check(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Gather");
    std::vector<float> all;
    if (everyone || root) {
        std::size_t total = 0;
        for (int i = 0; i < ranks; ++i) {
            displs[std::size_t(i)] = int(total);
            total += std::size_t(counts[std::size_t(i)]);
            FULGUR_ASSERT(total <= std::size_t(INT_MAX), "LatticeSlab: a lattice larger than 2^31 floats");
        }
        all.resize(total);
    }
    if (everyone)
        detail::check(MPI_Allgatherv(mine.data(), n, MPI_FLOAT, all.data(), counts.data(), displs.data(), MPI_FLOAT,
                                     MPI_COMM_WORLD),
                      "MPI_Allgatherv");
    else
        detail::check(MPI_Gatherv(mine.data(), n, MPI_FLOAT, all.data(), counts.data(), displs.data(), MPI_FLOAT, 0,
                                  MPI_COMM_WORLD),
                      "MPI_Gatherv");
    return all;
}
#endif

}  // namespace

std::vector<float> LatticeSlab::gather() const {
    std::vector<float> mine = own_sites(*kernel_, std::size_t(z1_ - z0_) * plane_);
#ifdef FULGUR_HAVE_MPI
    if (session_.size() > 1) return gather_slabs(mine, session_.size(), session_.rank() == 0, false);
#endif
    return mine;
}

std::vector<float> LatticeSlab::gather_all() const {
    std::vector<float> mine = own_sites(*kernel_, std::size_t(z1_ - z0_) * plane_);
#ifdef FULGUR_HAVE_MPI
    if (session_.size() > 1) return gather_slabs(mine, session_.size(), session_.rank() == 0, true);
#endif
    return mine;
}

}  // namespace fulgur::distributed
