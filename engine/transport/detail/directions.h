// Internal: the direction-interpolation tables shared by the CPU (direction_weights) and the
// renderer's GPU resolve pass (shaders/directions.glsl reads them as uniforms).
#pragma once

#include <array>

namespace fulgur::transport::detail {

/// Lattice code of a cube lattice vector v (components in {-1, 0, 1}): (x+1) + 3(y+1) + 9(z+1).
constexpr int lattice_code(int x, int y, int z) noexcept { return (x + 1) + 3 * (y + 1) + 9 * (z + 1); }

/// Where the weight of each of the 27 lattice vectors goes in a baked set of `count`
/// directions: up to three (output index, fraction) pairs; unused slots have index -1.
/// A lattice vector present in the set maps to itself; a missing one is split equally among
/// the vectors obtained by zeroing one of its non-zero components (recursively), so 18
/// directions hand each corner to its three edges and 6 hand edges/corners to their faces.
struct FoldTable {
    std::array<std::array<int, 3>, 27> index{};
    std::array<std::array<double, 3>, 27> fraction{};
};

/// Throws core::Error for a count other than 1, 6, 18, 26.
FoldTable fold_table(int direction_count);

}  // namespace fulgur::transport::detail
