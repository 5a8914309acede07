// The static light's solve over the ranks (distributed.h, docs/distributed.md): the sky
// module's Processes over MPI_COMM_WORLD and the lattice's kernel factory making this rank's
// z-slab (LatticeSlab).
#include "distributed/detail/lattice.h"
#include "distributed/distributed.h"

#ifdef FULGUR_HAVE_MPI
#include "distributed/detail/mpi.h"
#endif

#include <algorithm>
#include <chrono>
#include <climits>
#include <thread>

namespace fulgur::distributed {

namespace {

class Ranks final : public sky::Processes {
public:
    explicit Ranks(const Session& session) : session_(session) {}
    int rank() const override { return session_.rank(); }
    int size() const override { return session_.size(); }
    int broadcast(int value) const override { return session_.broadcast(value); }

    void share(std::span<float> data, int root) const override {
#ifdef FULGUR_HAVE_MPI
        if (session_.size() == 1) return;
        // The ranks reach an exchange at different times (the root may still be solving its
        // part): they meet at a barrier tested every millisecond, so a waiting rank leaves its
        // core to the others, then MPI_Bcast moves the data (in pieces an int counts).
        MPI_Request req;
        detail::check(MPI_Ibarrier(MPI_COMM_WORLD, &req), "MPI_Ibarrier");
        for (;;) {
            int done = 0;
            detail::check(MPI_Test(&req, &done, MPI_STATUS_IGNORE), "MPI_Test");
            if (done) break;
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
        constexpr std::size_t piece = std::size_t(1) << 28;
        for (std::size_t at = 0; at < data.size(); at += piece) {
            const int n = int(std::min(piece, data.size() - at));
            detail::check(MPI_Bcast(data.data() + at, n, MPI_FLOAT, root, MPI_COMM_WORLD), "MPI_Bcast");
        }
#else
        (void)data;
        (void)root;
#endif
    }

private:
    const Session& session_;
};

}  // namespace

sky::SolveSettings static_light_settings(const Session& session, sky::SolveSettings settings) {
    if (!session.distributed()) return settings;
    settings.processes = std::make_shared<Ranks>(session);
    settings.lattice.make_kernel =
        [&session](const transport::lb::Problem& p) -> std::unique_ptr<transport::lb::Kernel> {
        using transport::lb::Boundary;
        const bool open =
            p.boundary[0] == Boundary::Open && p.boundary[1] == Boundary::Open && p.boundary[2] == Boundary::Open;
        // A lattice too thin for 2 planes per rank is stepped whole on every rank (the same
        // fast kernel, so the same result).
        if (!open || p.dims.z < 2 * session.size()) return transport::lb::make_fast_kernel(p);
        return std::make_unique<LatticeSlab>(session, p);
    };
    return settings;
}

}  // namespace fulgur::distributed
