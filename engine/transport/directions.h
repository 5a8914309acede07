// fulgur::transport — interpolation of S between its baked output directions
// (output_directions): the weights a renderer, or anything else reading S toward an arbitrary
// direction, gives the stored directions.
#pragma once

#include <glm/vec3.hpp>

#include <array>

namespace fulgur::transport {

/// Up to four (direction, weight) pairs with weights >= 0 summing to 1.
struct DirectionWeights {
    int count = 0;
    std::array<int, 4> index{};
    std::array<double, 4> weight{};
};

/// Interpolation of S between the baked directions for direction `dir` (the direction from the
/// sample toward the viewer; need not be unit). For 26 directions (faces, edges, corners of a
/// cube): `dir` is projected onto the cube (gnomonic), each cube face is a 2x2 grid of cells
/// whose nodes are the face centre, edge midpoints and corners, and the weights are bilinear in
/// smoothstep-remapped cell coordinates: non-negative, partition of unity, exactly one
/// direction at a baked direction, C1 on the sphere. 18 directions give each corner's weight
/// in equal thirds to its three edge neighbours, 6 give edge (corner) weights in halves
/// (thirds) to the adjacent faces; 1 direction has weight 1. Mirrored in shaders/directions.glsl.
DirectionWeights direction_weights(const glm::dvec3& dir, int direction_count);

}  // namespace fulgur::transport
