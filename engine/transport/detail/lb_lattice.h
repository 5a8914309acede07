// Internal: the D3Q19 lattice of the lattice-Boltzmann solver (Geist et al. 2004, Fig. 1).
//
// Direction 0 is the rest direction (c = 0), 1..6 the axis directions (length 1),
// 7..18 the 12 face-diagonal directions (length sqrt 2). Opposite directions are adjacent
// (1<->2, 3<->4, ..., 17<->18), so opp(i) = i + 1 for odd i and i - 1 for even i >= 2.
// The isotropy weights w_i are 1/12 (axis) and 1/24 (diagonal): the paper's equilibrium v
// without its rest entry; they sum to 1 and give sum_i w_i c_ia c_ib = delta_ab / 2.
// Everything here is constexpr and checked by static_asserts at compile time.
#pragma once

#include <array>
#include <cmath>

namespace fulgur::transport::lb {

inline constexpr int kQ = 19;       ///< directions including rest
inline constexpr int kMoving = 18;  ///< directions 1..18

struct Velocity {
    int x, y, z;
};

inline constexpr std::array<Velocity, kQ> kVelocity = {{
    {0, 0, 0},                                                              // 0 rest
    {1, 0, 0}, {-1, 0, 0},  {0, 1, 0},  {0, -1, 0}, {0, 0, 1}, {0, 0, -1},  // 1..6 axes
    {1, 1, 0}, {-1, -1, 0}, {1, -1, 0}, {-1, 1, 0},                         // 7..10 xy
    {1, 0, 1}, {-1, 0, -1}, {1, 0, -1}, {-1, 0, 1},                         // 11..14 xz
    {0, 1, 1}, {0, -1, -1}, {0, 1, -1}, {0, -1, 1},                         // 15..18 yz
}};

/// Direction classes: 0 rest, 1 axis, 2 diagonal.
enum DirClass : int { kRest = 0, kAxis = 1, kDiagonal = 2 };

constexpr int dir_class(int i) noexcept { return i == 0 ? kRest : (i <= 6 ? kAxis : kDiagonal); }
constexpr int opposite(int i) noexcept { return i == 0 ? 0 : ((i % 2) ? i + 1 : i - 1); }
constexpr int length_squared(int i) noexcept {
    return kVelocity[std::size_t(i)].x * kVelocity[std::size_t(i)].x +
           kVelocity[std::size_t(i)].y * kVelocity[std::size_t(i)].y +
           kVelocity[std::size_t(i)].z * kVelocity[std::size_t(i)].z;
}
/// Isotropy weight in units of 1/24 (exact integer arithmetic for the static checks).
constexpr int weight24(int i) noexcept { return i == 0 ? 0 : (dir_class(i) == kAxis ? 2 : 1); }
/// Isotropy weight w_i: 1/12 axis, 1/24 diagonal, 0 rest.
constexpr double weight(int i) noexcept { return double(weight24(i)) / 24.0; }
/// Integer dot product c_i . c_j.
constexpr int cdot(int i, int j) noexcept {
    return kVelocity[std::size_t(i)].x * kVelocity[std::size_t(j)].x +
           kVelocity[std::size_t(i)].y * kVelocity[std::size_t(j)].y +
           kVelocity[std::size_t(i)].z * kVelocity[std::size_t(j)].z;
}
/// Hop length |c_i| in lattice spacings (0, 1 or sqrt 2).
inline double hop_length(int i) noexcept { return std::sqrt(double(length_squared(i))); }
/// Cosine between the normalized directions n_i . n_j (i, j >= 1).
inline double cosine(int i, int j) noexcept {
    return double(cdot(i, j)) / std::sqrt(double(length_squared(i) * length_squared(j)));
}

namespace detail {
constexpr bool check_table() {
    // Classes and lengths.
    if (length_squared(0) != 0) return false;
    for (int i = 1; i < kQ; ++i) {
        const int l2 = length_squared(i);
        if (dir_class(i) == kAxis && l2 != 1) return false;
        if (dir_class(i) == kDiagonal && l2 != 2) return false;
        const Velocity& c = kVelocity[std::size_t(i)];
        if (c.x < -1 || c.x > 1 || c.y < -1 || c.y > 1 || c.z < -1 || c.z > 1) return false;
    }
    // All 18 non-corner neighbours of {-1,0,1}^3 appear exactly once.
    for (int i = 0; i < kQ; ++i)
        for (int j = i + 1; j < kQ; ++j)
            if (kVelocity[std::size_t(i)].x == kVelocity[std::size_t(j)].x &&
                kVelocity[std::size_t(i)].y == kVelocity[std::size_t(j)].y &&
                kVelocity[std::size_t(i)].z == kVelocity[std::size_t(j)].z)
                return false;
    return true;
}
constexpr bool check_opposites() {
    for (int i = 0; i < kQ; ++i) {
        const int o = opposite(i);
        if (opposite(o) != i) return false;
        if (dir_class(o) != dir_class(i)) return false;
        const Velocity& a = kVelocity[std::size_t(i)];
        const Velocity& b = kVelocity[std::size_t(o)];
        if (a.x != -b.x || a.y != -b.y || a.z != -b.z) return false;
    }
    return true;
}
constexpr bool check_weights() {
    int sum = 0, sx = 0, sy = 0, sz = 0;
    int m[3][3] = {};
    for (int i = 0; i < kQ; ++i) {
        const Velocity& c = kVelocity[std::size_t(i)];
        sum += weight24(i);
        sx += weight24(i) * c.x;
        sy += weight24(i) * c.y;
        sz += weight24(i) * c.z;
        const int v[3] = {c.x, c.y, c.z};
        for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) m[a][b] += weight24(i) * v[a] * v[b];
    }
    if (sum != 24) return false;                      // sum w_i = 1
    if (sx != 0 || sy != 0 || sz != 0) return false;  // sum w_i c_i = 0
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            if (m[a][b] != (a == b ? 12 : 0)) return false;  // sum w_i c_ia c_ib = delta_ab / 2
    return true;
}
constexpr bool check_symmetry() {
    // Cubic symmetry: the number of directions at each cosine is the same for every
    // direction of a class (this is what lets the collision be factored by class).
    for (int i = 1; i < kQ; ++i) {
        int counts[5] = {};  // c_i . c_j in {-2..2}
        for (int j = 1; j < kQ; ++j) counts[cdot(i, j) + 2]++;
        const int ref = dir_class(i) == kAxis ? 1 : 7;
        int rc[5] = {};
        for (int j = 1; j < kQ; ++j) rc[cdot(ref, j) + 2]++;
        for (int k = 0; k < 5; ++k)
            if (counts[k] != rc[k]) return false;
    }
    return true;
}
}  // namespace detail

static_assert(detail::check_table(),
              "D3Q19 velocity table must list the 18 non-corner neighbours once, classes by length");
static_assert(detail::check_opposites(), "opposite(i) must be the reversed velocity of the same class");
static_assert(detail::check_weights(), "isotropy weights: sum 1, zero first moment, second moment delta/2");
static_assert(detail::check_symmetry(), "every direction of a class must see the same cosine multiset");
static_assert(weight24(1) == 2 && weight24(7) == 1, "weights are 1/12 (axis) and 1/24 (diagonal)");

}  // namespace fulgur::transport::lb
