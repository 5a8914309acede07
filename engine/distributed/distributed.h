// fulgur::distributed — a bake over several processes (docs/distributed.md): the processes
// of an MPI run (mpirun, srun) share the plan's lights dynamically and rank 0 writes the one
// .fgb, byte-identical to a single process's bake of the same scene.
//
// No MPI type appears in this header: MPI stays inside the module's sources, and a build
// without MPI (FULGUR_MPI off) has the same interface, every process being rank 0 of 1.
#pragma once

#include "bake/bake.h"

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

}  // namespace fulgur::distributed
