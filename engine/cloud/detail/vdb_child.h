// Internal to fulgur::cloud: the reading child's entry points (vdb_child.cpp, the only file
// that runs OpenVDB's reader). The parent (vdb_parent.h) forks, and the child runs
// child_main with a body that writes its records to an Out.
#pragma once

#include "cloud/cloud.h"

#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <functional>

namespace fulgur::cloud::detail::vdb {

// The child's records, buffered (defined in vdb_child.cpp).
class Out;

// What a child does: reads the file and writes its records.
using ChildBody = std::function<void(Out&)>;

// Loads OpenVDB's grid types once; before the first fork, so the children inherit them.
void initialize_openvdb();

// Runs in the forked child: limits its core files, CPU time (`seconds`) and memory (`budget`
// plus kLibraryBytes; `first` plus kLibraryBytes until the descriptors are checked), keeps only
// the pipe `fd` open, runs `body` and exits; an exception becomes an error record. Everything
// the parent needs from it is on the pipe.
[[noreturn]] void child_main(int fd, pid_t parent, std::uint64_t budget, std::uint64_t first, double seconds,
                             const ChildBody& body);

// inspect_vdb's child: the descriptors.
void child_inspect(const std::filesystem::path& path, Out& out);

// load_vdb's child: the descriptors, then (if the parent will want them: the same inspect()
// and size check it runs) the chosen grid's background, active box, leaves and tiles.
void child_load(const std::filesystem::path& path, const VdbImport& options, Out& out);

}  // namespace fulgur::cloud::detail::vdb
