// Internal: the checkpoint of a bake (BakeOptions::checkpoint, docs/distributed.md). A
// directory holding, for every finished chunk of lights [b, e):
//   lights-<b>-<e>.stats  the chunk's figures (encode_results without blocks) under a header
//                         naming the format version, the scene key's hash and the range, with
//                         a CRC-32 of everything before it at the end;
//   lights-<b>-<e>.fgb    its blocks, a partial .fgb (basis::FgbWriter: header and block CRCs,
//                         the full metadata, the range).
// Both are written atomically (core::AtomicFile), the figures first: a chunk is held when its
// .fgb is, and a kill between the two leaves only figures, which are written again.
#pragma once

#include "bake/bake.h"

#include <mutex>
#include <utility>

namespace fulgur::bake::detail {

class Checkpoint {
public:
    /// Creates the directory, or checks every chunk it holds against the plan: each .fgb's
    /// header, metadata (scene key, grids, directions, compression: FgbReader::check_metadata)
    /// and block CRCs; each .stats file's size, CRC, version, key and range, and that its
    /// figures belong to the blocks (block CRCs and sizes); ranges inside the plan and
    /// disjoint. Throws core::Error naming the file and what is wrong. Leftover temporaries
    /// and figures without blocks (a killed writer's) are removed.
    Checkpoint(std::filesystem::path dir, const Plan& plan);

    struct Held {
        Chunk chunk;
        std::vector<LightResult> figures;  ///< no blocks
    };
    /// The chunks held, in light order.
    const std::vector<Held>& held() const noexcept { return held_; }
    std::size_t lights() const {
        std::lock_guard lock(mutex_);
        return lights_;
    }
    const std::filesystem::path& dir() const noexcept { return dir_; }

    /// Stores a finished chunk (figures, then blocks). Thread-safe.
    void add(Chunk c, std::span<const LightResult> results);
    /// Adds every held block to `writer`, in light order (each block's CRC checked again).
    void copy_blocks(basis::FgbWriter& writer);
    /// Removes the directory and everything in it.
    void remove();

    /// The file names of a chunk.
    static std::string stem(Chunk c);

private:
    std::filesystem::path dir_;
    basis::FgbMetadata meta_;
    std::vector<Held> held_;
    std::size_t lights_ = 0;
    mutable std::mutex mutex_;
};

}  // namespace fulgur::bake::detail
