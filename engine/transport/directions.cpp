// Interpolation of S between the baked output directions (transport/directions.h): the
// fold table that hands a lattice vector missing from the set to its neighbours, and the
// smooth cube-face weights. The renderer's resolve pass mirrors it (shaders/directions.glsl).
#include "transport/directions.h"
#include "transport/detail/directions.h"

#include "core/error.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>
#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace fulgur::transport {

namespace detail {

namespace {

/// The baked set's index of lattice vector v, or -1 when the set does not contain it.
int find_index(const std::vector<glm::dvec3>& dirs, const glm::ivec3& v) {
    const glm::dvec3 n = glm::normalize(glm::dvec3(v));
    for (std::size_t i = 0; i < dirs.size(); ++i)
        if (glm::length(dirs[i] - n) < 1e-9) return int(i);
    return -1;
}

void fold(const std::vector<glm::dvec3>& dirs, const glm::ivec3& v, double share, std::map<int, double>& out) {
    const int i = find_index(dirs, v);
    if (i >= 0) {
        out[i] += share;
        return;
    }
    int nonzero = 0;
    for (int a = 0; a < 3; ++a) nonzero += v[a] != 0;
    FULGUR_ASSERT(nonzero > 1, "a face direction is missing from the baked set");
    for (int a = 0; a < 3; ++a)
        if (v[a] != 0) {
            glm::ivec3 w = v;
            w[a] = 0;
            fold(dirs, w, share / nonzero, out);
        }
}

}  // namespace

FoldTable fold_table(int direction_count) {
    const std::vector<glm::dvec3> dirs = transport::output_directions(direction_count);  // validates the count
    FoldTable t;
    for (auto& a : t.index) a.fill(-1);
    for (auto& a : t.fraction) a.fill(0.0);
    for (int z = -1; z <= 1; ++z)
        for (int y = -1; y <= 1; ++y)
            for (int x = -1; x <= 1; ++x) {
                const int code = lattice_code(x, y, z);
                if (x == 0 && y == 0 && z == 0) continue;
                std::map<int, double> parts;
                if (direction_count == 1)
                    parts[0] = 1.0;
                else
                    fold(dirs, {x, y, z}, 1.0, parts);
                FULGUR_ASSERT(parts.size() <= 3, "fold produced more than three targets");
                int k = 0;
                for (const auto& [idx, frac] : parts) {
                    t.index[std::size_t(code)][std::size_t(k)] = idx;
                    t.fraction[std::size_t(code)][std::size_t(k)] = frac;
                    ++k;
                }
            }
    return t;
}

}  // namespace detail

namespace {

double smooth(double f) noexcept { return f * f * (3.0 - 2.0 * f); }

/// The four lattice nodes of the cube-face cell containing `d` and their weights (before
/// folding). Mirrors cube_cell_weights() in shaders/directions.glsl, tie-breaking included.
void cube_cell(const glm::dvec3& d, std::array<int, 4>& code, std::array<double, 4>& w) {
    const glm::dvec3 ad = glm::abs(d);
    const int a = (ad.x >= ad.y && ad.x >= ad.z) ? 0 : (ad.y >= ad.z ? 1 : 2);
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const double u = d[b] / ad[a], v = d[c] / ad[a];
    const int sa = d[a] >= 0.0 ? 1 : -1, su = u >= 0.0 ? 1 : -1, sv = v >= 0.0 ? 1 : -1;
    const double fu = smooth(std::min(std::abs(u), 1.0)), fv = smooth(std::min(std::abs(v), 1.0));
    auto node = [&](int du, int dv) {
        glm::ivec3 l(0);
        l[a] = sa;
        l[b] = du;
        l[c] = dv;
        return detail::lattice_code(l.x, l.y, l.z);
    };
    code = {node(0, 0), node(su, 0), node(0, sv), node(su, sv)};
    w = {(1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv};
}

}  // namespace

DirectionWeights direction_weights(const glm::dvec3& dir, int direction_count) {
    static thread_local int cached_count = -1;
    static thread_local detail::FoldTable table;
    if (cached_count != direction_count) {
        table = detail::fold_table(direction_count);
        cached_count = direction_count;
    }
    DirectionWeights out;
    if (direction_count == 1) {
        out.count = 1;
        out.index[0] = 0;
        out.weight[0] = 1.0;
        return out;
    }
    const double len = glm::length(dir);
    FULGUR_ASSERT(std::isfinite(len) && len > 0.0, "direction_weights needs a finite non-zero direction");
    std::array<int, 4> code;
    std::array<double, 4> w;
    cube_cell(dir / len, code, w);
    for (int n = 0; n < 4; ++n) {
        if (w[std::size_t(n)] <= 0.0) continue;
        for (int k = 0; k < 3; ++k) {
            const int idx = table.index[std::size_t(code[std::size_t(n)])][std::size_t(k)];
            if (idx < 0) break;
            const double share =
                w[std::size_t(n)] * (table.fraction[std::size_t(code[std::size_t(n)])][std::size_t(k)]);
            int slot = 0;
            while (slot < out.count && out.index[std::size_t(slot)] != idx) ++slot;
            if (slot == out.count) {
                FULGUR_ASSERT(out.count < 4, "more than four directions in one cell");
                out.index[std::size_t(slot)] = idx;
                out.weight[std::size_t(slot)] = 0.0;
                ++out.count;
            }
            out.weight[std::size_t(slot)] += share;
        }
    }
    return out;
}

}  // namespace fulgur::transport
