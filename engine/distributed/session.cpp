// The process's place in a distributed run (distributed.h) and the module's MPI helpers
// (detail/mpi.h).
#include "distributed/distributed.h"

#ifdef FULGUR_HAVE_MPI
#include "distributed/detail/mpi.h"
#endif

#include <chrono>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <thread>

namespace fulgur::distributed {

namespace {

// A process started by an MPI launcher: Open MPI's mpirun, PMIx (srun --mpi=pmix, prrte),
// PMI-1/2 (Hydra's mpiexec, srun --mpi=pmi2).
bool launched_by_mpi() {
    for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
        if (std::getenv(v)) return true;
    return false;
}

}  // namespace

#ifdef FULGUR_HAVE_MPI

namespace detail {

void check(int code, const char* call) {
    if (code == MPI_SUCCESS) return;
    char text[MPI_MAX_ERROR_STRING];
    int n = 0;
    MPI_Error_string(code, text, &n);
    throw core::Error(call, std::string(text, std::size_t(n)));
}

MPI_Status wait_for(int source, int tag) {
    MPI_Status st;
    for (;;) {
        int flag = 0;
        check(MPI_Iprobe(source, tag, MPI_COMM_WORLD, &flag, &st), "MPI_Iprobe");
        if (flag) return st;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

std::vector<std::uint8_t> receive_bytes(const MPI_Status& status) {
    int count = 0;
    check(MPI_Get_count(&status, MPI_BYTE, &count), "MPI_Get_count");
    std::vector<std::uint8_t> bytes(std::size_t(count > 0 ? count : 0));
    check(MPI_Recv(bytes.data(), count, MPI_BYTE, status.MPI_SOURCE, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
          "MPI_Recv");
    return bytes;
}

void send_bytes(std::span<const std::uint8_t> bytes, int dest, int tag) {
    FULGUR_ASSERT(bytes.size() <= std::size_t(INT_MAX), "send_bytes: a message larger than 2 GiB");
    check(MPI_Send(bytes.data(), int(bytes.size()), MPI_BYTE, dest, tag, MPI_COMM_WORLD), "MPI_Send");
}

}  // namespace detail

bool available() noexcept { return true; }

Session::Session(int& argc, char**& argv) {
    if (!launched_by_mpi()) return;
    int provided = 0;
    detail::check(MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
    joined_ = true;
    if (provided < MPI_THREAD_FUNNELED) {
        std::fprintf(stderr, "MPI provides no thread support (MPI_THREAD_FUNNELED needed)\n");
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

Session::~Session() {
    if (joined_) MPI_Finalize();
}

int Session::broadcast(int value) const {
    if (size_ == 1) return value;
    if (rank_ == 0) {
        for (int r = 1; r < size_; ++r)
            detail::check(MPI_Send(&value, 1, MPI_INT, r, detail::kTagBroadcast, MPI_COMM_WORLD), "MPI_Send");
        return value;
    }
    const MPI_Status st = detail::wait_for(0, detail::kTagBroadcast);
    detail::check(MPI_Recv(&value, 1, MPI_INT, st.MPI_SOURCE, st.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
                  "MPI_Recv");
    return value;
}

void Session::abort(int code) const {
    std::fflush(stdout);
    std::fflush(stderr);
    if (joined_) MPI_Abort(MPI_COMM_WORLD, code);
    std::exit(code);
}

#else  // a build without MPI: every process is rank 0 of 1

bool available() noexcept { return false; }

Session::Session(int&, char**&) {
    if (launched_by_mpi())
        std::fprintf(stderr,
                     "warning: started by an MPI launcher, but this build has no MPI (FULGUR_MPI off): "
                     "every process runs alone\n");
}

Session::~Session() = default;

int Session::broadcast(int value) const { return value; }

void Session::abort(int code) const {
    std::fflush(stdout);
    std::fflush(stderr);
    std::exit(code);
}

#endif

}  // namespace fulgur::distributed
