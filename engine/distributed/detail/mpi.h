// Internal: the few MPI helpers the module's sources share. Included only where
// FULGUR_HAVE_MPI is defined (the module's CMakeLists links MPI then).
#pragma once

#include "core/core.h"

#include <mpi.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace fulgur::distributed::detail {

/// Message tags of the module's protocols.
enum Tag : int {
    kTagBroadcast = 1,  ///< Session::broadcast: rank 0's value
    kTagResult = 2,     ///< bake, helper -> rank 0: [begin u32][end u32][encode_results with blocks]
    kTagWork = 3,       ///< bake, rank 0 -> helper: [begin u32][end u32]; begin == end: no work left
    kTagError = 4,      ///< bake, helper -> rank 0: the text of the helper's failure
};

/// Throws core::Error naming the call unless `code` is MPI_SUCCESS.
void check(int code, const char* call);

/// Waits (polling every millisecond, so a waiting rank leaves its core to the others) until a
/// message from `source` with `tag` can be received; returns its status.
MPI_Status wait_for(int source, int tag);

/// Receives the message `status` announced, as bytes.
std::vector<std::uint8_t> receive_bytes(const MPI_Status& status);

/// Sends bytes (their count must fit an int: FULGUR_ASSERT).
void send_bytes(std::span<const std::uint8_t> bytes, int dest, int tag);

}  // namespace fulgur::distributed::detail
