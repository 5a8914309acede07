// fulgur::distributed — a bake over several processes (docs/distributed.md): the processes
// of an MPI run (mpirun, srun) share the plan's lights dynamically and rank 0 writes the one
// .fgb, byte-identical to a single process's bake of the same scene; the static light (the
// sun's and the sky's solves) over the same processes, bit-identical to one process's.
//
// No MPI type appears in this header: MPI stays inside the module's sources, and a build
// without MPI (FULGUR_MPI off) has the same interface, every process being rank 0 of 1.
#pragma once

#include "bake/bake.h"
#include "sky/sky.h"

#include <optional>

namespace fulgur::distributed {

/// True when this build has MPI (FULGUR_MPI).
bool available() noexcept;

/// This process's place in a distributed run. A process started by an MPI launcher (mpirun,
/// mpiexec, srun; recognised by the variables they set) joins MPI_COMM_WORLD
/// (MPI_Init_thread, MPI_THREAD_FUNNELED: only the thread that created the Session calls MPI);
/// any other process is rank 0 of 1 and never touches MPI, so a tool runs as it always did.
/// One per process, created first in main(), destroyed last (MPI_Finalize).
class Session {
public:
    Session(int& argc, char**& argv);
    ~Session();
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;

    int rank() const noexcept { return rank_; }
    int size() const noexcept { return size_; }
    bool distributed() const noexcept { return size_ > 1; }
    /// Rank 0's `value`, on every rank. Waiting ranks poll (they do not spin a core).
    int broadcast(int value) const;
    /// Ends every rank's process after a failure on this one (MPI_Abort; std::exit alone).
    [[noreturn]] void abort(int code) const;

private:
    int rank_ = 0, size_ = 1;
    bool joined_ = false;
};

/// Bakes the plan over every rank: rank 0 runs bake::bake with the other ranks as its
/// Helpers (it writes `out` and the checkpoint, and reports progress over all ranks); each
/// other rank solves the chunks rank 0 hands it, with plan.threads threads, until none is
/// left. Every rank passes the same scene and plan (their scene keys are compared first).
/// Rank 0 returns the report, the others nothing. With one rank: bake::bake.
std::optional<bake::Report> bake(const Session& session, const scene::Scene& s, const core::Grid3<float>& density,
                                 const bake::Plan& plan, const std::filesystem::path& out,
                                 const bake::BakeOptions& options = {}, const bake::Progress& progress = {});

/// `settings` with the static light's solve spread over every rank of `session` (sky::
/// SolveSettings::processes and transport::LbSettings::make_kernel): the sky's dome samples
/// dealt round by round, the sun's single scattering (rank 0) and order-2 Monte Carlo (rank 1)
/// at once, exchanged with MPI_Bcast; the lattice stepped in z-slabs (LatticeSlab; the whole
/// lattice on every rank when it has fewer than 2 planes per rank) and all-gathered for the
/// read-out. Every rank then makes the same sky calls (solve_directional, solve_sun, solve_sky,
/// load_or_solve) in the same order, on the thread that created the Session, and each returns
/// the one-process result bit for bit. `session` must outlive the settings. One rank:
/// `settings` unchanged.
sky::SolveSettings static_light_settings(const Session& session, sky::SolveSettings settings);

}  // namespace fulgur::distributed
