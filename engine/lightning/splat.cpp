// Trilinear splatting of point sources into the virtual lights (Dobashi et al. 2007, Eq. 6).
//
// A source at p in cell (i, j, k) with fractions (fx, fy, fz) gives light (i+a, j+b, k+c)
// the weight wx_a * wy_b * wz_c, with wx_0 = 1 - fx, wx_1 = fx (likewise y, z). The eight
// weights sum to (wx_0 + wx_1)(wy_0 + wy_1)(wz_0 + wz_1) = 1, so sum_l e_l = sum_q L_q; in
// double precision the two sums agree to a few ulps per source.
//
// Outside the grid: each coordinate is clamped to [first node, last node] of its axis, i.e.
// the source moves to the nearest point of the grid's bounding box and its energy goes to
// the lights of the boundary cell there (face, edge or corner). Such sources are counted
// (LightWeights::clamped). Non-finite positions or intensities are skipped and counted
// (LightWeights::rejected): they never produce NaN in e_l.
#include "lightning/lightning.h"

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace fulgur::lightning {

namespace {

Splatter::Axis make_axis(const std::vector<double>& nodes, const char* name, double& min_spacing) {
    const std::string where = std::string("virtual-light grid: axis ") + name;
    if (nodes.empty()) throw core::Error(where, "has no nodes");
    if (nodes.size() > (std::size_t(1) << 20)) throw core::Error(where, "has more than 2^20 nodes");
    Splatter::Axis a;
    a.nodes = nodes;
    double dmin = 1e300;
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        if (!std::isfinite(nodes[i])) throw core::Error(where, "node " + std::to_string(i) + " is not finite");
        if (i > 0) {
            const double d = nodes[i] - nodes[i - 1];
            if (!(d > 0.0))
                throw core::Error(where, "nodes must be strictly ascending (node " + std::to_string(i) + ")");
            dmin = std::min(dmin, d);
        }
    }
    if (nodes.size() == 1) return a;  // a single layer: every source lands on it
    min_spacing = std::min(min_spacing, dmin);
    // Uniform bins of width dmin (at most 4096 bins; wider bins only lengthen the walk):
    // lut[b] = the cell holding the bin's lower edge.
    const double span = nodes.back() - nodes.front();
    const double bins = std::min(4096.0, std::ceil(span / dmin));
    const double width = span / bins;
    a.inv_bin = 1.0 / width;
    a.lut.resize(std::size_t(bins) + 1);
    std::uint32_t cell = 0;
    const std::uint32_t last_cell = std::uint32_t(nodes.size() - 2);
    for (std::size_t b = 0; b < a.lut.size(); ++b) {
        const double x = nodes.front() + double(b) * width;
        while (cell < last_cell && nodes[cell + 1] <= x) ++cell;
        a.lut[b] = cell;
    }
    return a;
}

}  // namespace

void Splatter::Axis::locate(double v, std::uint32_t& i, double& f) const noexcept {
    const std::size_t n = nodes.size();
    if (n == 1) {
        i = 0;
        f = 0.0;
        return;
    }
    const std::uint32_t last_cell = std::uint32_t(n - 2);
    std::size_t b = std::size_t((v - nodes.front()) * inv_bin);  // v >= nodes.front(): non-negative
    b = std::min(b, lut.size() - 1);
    std::uint32_t c = lut[b];
    while (c < last_cell && nodes[c + 1] <= v) ++c;  // bins no wider than a cell: a step or two
    while (c > 0 && nodes[c] > v) --c;               // rounding in the bin index
    i = c;
    f = std::clamp((v - nodes[c]) / (nodes[c + 1] - nodes[c]), 0.0, 1.0);
}

void Splatter::Axis::locate_bsearch(double v, std::uint32_t& i, double& f) const noexcept {
    const std::size_t n = nodes.size();
    if (n == 1) {
        i = 0;
        f = 0.0;
        return;
    }
    // First node > v, minus one: the cell's lower node; the last node maps to the last cell.
    const auto it = std::upper_bound(nodes.begin(), nodes.end(), v);
    std::size_t c = std::size_t(std::max<std::ptrdiff_t>(0, (it - nodes.begin()) - 1));
    c = std::min(c, n - 2);
    i = std::uint32_t(c);
    f = std::clamp((v - nodes[c]) / (nodes[c + 1] - nodes[c]), 0.0, 1.0);
}

Splatter::Splatter(const basis::VirtualLightGrid& grid) {
    min_spacing_ = 1e300;
    ax_[0] = make_axis(grid.x, "x", min_spacing_);
    ax_[1] = make_axis(grid.y, "y", min_spacing_);
    ax_[2] = make_axis(grid.z, "z", min_spacing_);
    if (min_spacing_ == 1e300)
        throw core::Error("virtual-light grid", "a grid of a single light has no spacing to place point sources by");
    count_ = grid.count();
    if (count_ > (std::size_t(1) << 31)) throw core::Error("virtual-light grid", "more than 2^31 lights");
    for (int k = 0; k < 3; ++k) {
        box_.lo[k] = ax_[k].nodes.front();
        box_.hi[k] = ax_[k].nodes.back();
    }
}

void Splatter::reset(LightWeights& out) const {
    if (out.e.size() != count_) {
        out.e.assign(count_, 0.0);
        out.touched.assign(count_, 0);
        out.active.clear();
    } else {
        for (const std::uint32_t l : out.active) out.e[l] = 0.0, out.touched[l] = 0;
        out.active.clear();
    }
    if (out.touched.size() != count_) out.touched.assign(count_, 0);
    out.total = 0.0;
    out.sources = out.clamped = out.rejected = 0;
}

void Splatter::splat(std::span<const transport::PointSource> sources, LightWeights& out) const {
    reset(out);
    accumulate(sources, out);
}

void Splatter::accumulate(std::span<const transport::PointSource> sources, LightWeights& out) const {
    accumulate_impl<true>(sources, out);
}

void Splatter::accumulate_binary_search(std::span<const transport::PointSource> sources, LightWeights& out) const {
    accumulate_impl<false>(sources, out);
}

template <bool kLut>
void Splatter::accumulate_impl(std::span<const transport::PointSource> sources, LightWeights& out) const {
    FULGUR_ASSERT(out.e.size() == count_ && out.touched.size() == count_,
                  "LightWeights must be sized for this grid (call Splatter::reset or splat first)");
    const std::size_t nx = ax_[0].nodes.size(), nxy = nx * ax_[1].nodes.size();
    // Offsets to the upper neighbour per axis: 0 on a single-node axis (its weight is 0 then).
    const std::size_t ox = nx > 1 ? 1 : 0, oy = ax_[1].nodes.size() > 1 ? nx : 0,
                      oz = ax_[2].nodes.size() > 1 ? nxy : 0;
    double* e = out.e.data();
    std::uint8_t* touched = out.touched.data();
    core::CompensatedSum total;
    total.add(out.total);
    for (const transport::PointSource& q : sources) {
        const glm::dvec3 p = q.position;
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || !std::isfinite(q.intensity)) {
            ++out.rejected;
            continue;
        }
        ++out.sources;
        const glm::dvec3 c = glm::clamp(p, box_.lo, box_.hi);
        if (c != p) ++out.clamped;
        std::uint32_t i, j, k;
        double fx, fy, fz;
        if constexpr (kLut) {
            ax_[0].locate(c.x, i, fx);
            ax_[1].locate(c.y, j, fy);
            ax_[2].locate(c.z, k, fz);
        } else {
            ax_[0].locate_bsearch(c.x, i, fx);
            ax_[1].locate_bsearch(c.y, j, fy);
            ax_[2].locate_bsearch(c.z, k, fz);
        }
        total.add(q.intensity);
        const double wx[2] = {1.0 - fx, fx}, wy[2] = {1.0 - fy, fy}, wz[2] = {1.0 - fz, fz};
        const std::size_t base = std::size_t(i) + nx * std::size_t(j) + nxy * std::size_t(k);
        for (int cz = 0; cz < 2; ++cz)
            for (int cy = 0; cy < 2; ++cy) {
                const double wyz = wy[cy] * wz[cz] * q.intensity;
                for (int cx = 0; cx < 2; ++cx) {
                    const double v = wx[cx] * wyz;
                    if (v == 0.0) continue;  // a zero weight (on a node or a boundary) touches nothing
                    const std::size_t l = base + (cx ? ox : 0) + (cy ? oy : 0) + (cz ? oz : 0);
                    e[l] += v;
                    if (!touched[l]) touched[l] = 1, out.active.push_back(std::uint32_t(l));
                }
            }
    }
    out.total = total.value();
    // Exact cancellation (sources of opposite sign) can leave e_l == 0: drop those. Then sort:
    // a dense list is rebuilt by one ordered scan (cheaper than sorting it).
    if (out.active.size() * 8 > count_) {
        out.active.clear();
        for (std::size_t l = 0; l < count_; ++l) {
            if (!touched[l]) continue;
            if (e[l] != 0.0)
                out.active.push_back(std::uint32_t(l));
            else
                touched[l] = 0;
        }
        return;
    }
    std::size_t w = 0;
    for (const std::uint32_t l : out.active) {
        if (e[l] != 0.0)
            out.active[w++] = l;
        else
            touched[l] = 0;
    }
    out.active.resize(w);
    std::sort(out.active.begin(), out.active.end());
}

}  // namespace fulgur::lightning
