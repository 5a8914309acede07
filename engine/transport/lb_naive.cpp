// The naive kernel, straight from the paper's Appendix B: nodes hold 19 floats (AoS); each
// step builds the site's dense 19x19 Theta (sigma entries scaled by the local density),
// multiplies, then a separate pass flows every density to its neighbour in a second
// lattice. Kept simple on purpose: it is the reference the fast kernel is tested against.
#include "transport/detail/lb_solver.h"

#include <algorithm>

namespace fulgur::transport::lb {

namespace {

class NaiveKernel final : public Kernel {
public:
    explicit NaiveKernel(const Problem& p) : p_(p), src_(p.sites()), dst_(p.sites()), src_out_(p.sites(), -1) {
        for (auto& n : src_) n.fill(0.0f);
        for (auto& n : dst_) n.fill(0.0f);
        for (std::size_t k = 0; k < p.sources.size(); ++k) src_out_[p.sources[k].site] = std::int64_t(k);
        // In-links of open faces: every (site, dir) whose upstream neighbour is outside.
        std::vector<float> inflow_value(p.sites() * kQ, 0.0f);
        for (const auto& in : p.inflow) inflow_value[in.site * kQ + std::size_t(in.dir)] += in.value;
        for (int z = 0; z < p.dims.z; ++z)
            for (int y = 0; y < p.dims.y; ++y)
                for (int x = 0; x < p.dims.x; ++x)
                    for (int q = 1; q < kQ; ++q) {
                        const Velocity& c = kVelocity[std::size_t(q)];
                        int n[3] = {x - c.x, y - c.y, z - c.z};
                        if (!neighbour(n)) {
                            const std::size_t s = p.index(x, y, z);
                            in_links_.push_back({s, q, inflow_value[s * kQ + std::size_t(q)]});
                        }
                    }
        for (const auto& l : in_links_) {
            src_[l.site][std::size_t(l.dir)] = l.value;  // first arrival at t = 0
            last_total_ += double(l.value);
        }
    }

    void step() override {
        const Problem& p = p_;
        const bool conservative = p.absorption == LbAbsorption::Conservative;
        double absorbed = 0.0, escaped = 0.0, total = 0.0;
        // Distribute density locally according to the collision rules.
        for (std::size_t i = 0; i < p.sites(); ++i) {
            const double eA = p.ext_axis[i], eD = p.ext_diag[i];
            float theta[kQ][kQ];
            for (int in = 0; in < kQ; ++in) {
                const double e = in == 0 ? 0.0 : (dir_class(in) == kAxis ? eA : eD);
                for (int out = 0; out < kQ; ++out) {
                    double t;
                    if (in == 0)
                        t = out == 0 ? 0.0 : weight(out);
                    else if (out == 0)
                        t = conservative ? (1.0 - p.albedo) * e : 0.0;
                    else
                        t = (out == in ? 1.0 - e : 0.0) + p.albedo * e * p.phase.P[std::size_t(out)][std::size_t(in)];
                    theta[in][out] = float(t);
                }
                if (!conservative && in > 0) absorbed += (1.0 - p.albedo) * e * double(src_[i][std::size_t(in)]);
            }
            float new_dense[kQ] = {};
            for (int in = 0; in < kQ; ++in)
                for (int out = 0; out < kQ; ++out) new_dense[out] += src_[i][std::size_t(in)] * theta[in][out];
            if (src_out_[i] >= 0) {
                const auto& s = p.sources[std::size_t(src_out_[i])].out;
                for (int q = 0; q < kQ; ++q) new_dense[q] += s[std::size_t(q)];
            }
            for (int q = 0; q < kQ; ++q) {
                src_[i][std::size_t(q)] = new_dense[q];
                total += double(new_dense[q]);
            }
        }
        // Now flow density to neighbours.
        for (int z = 0; z < p.dims.z; ++z)
            for (int y = 0; y < p.dims.y; ++y)
                for (int x = 0; x < p.dims.x; ++x) {
                    const std::size_t i = p.index(x, y, z);
                    dst_[i][0] = src_[i][0];
                    for (int q = 1; q < kQ; ++q) {
                        const Velocity& c = kVelocity[std::size_t(q)];
                        int n[3] = {x + c.x, y + c.y, z + c.z};
                        if (neighbour(n))
                            dst_[p.index(n[0], n[1], n[2])][std::size_t(q)] = src_[i][std::size_t(q)];
                        else
                            escaped += double(src_[i][std::size_t(q)]);
                    }
                }
        // Inject new light on the borders (the in-links nobody streamed into).
        for (const auto& l : in_links_) {
            dst_[l.site][std::size_t(l.dir)] = l.value;
            total += double(l.value);
        }
        std::swap(src_, dst_);
        last_total_ = total - escaped;
        last_absorbed_ = absorbed + p.source_absorbed_per_step;
        last_escaped_ = escaped;
        ++steps_;
    }

    double last_absorbed() const override { return last_absorbed_; }
    double last_escaped() const override { return last_escaped_; }
    double last_total() const override { return last_total_; }
    double stored() const override {
        double s = 0.0;
        for (const auto& n : src_)
            for (float v : n) s += double(v);
        return s;
    }
    float arriving(std::size_t site, int q) const override { return src_[site][std::size_t(q)]; }
    void set_arriving(std::size_t site, int q, float v) override {
        FULGUR_ASSERT(steps_ == 0, "set_arriving only before the first step");
        src_[site][std::size_t(q)] = v;
    }

private:
    // Wraps periodic axes; false if the point is outside an open face.
    bool neighbour(int n[3]) const {
        const int d[3] = {p_.dims.x, p_.dims.y, p_.dims.z};
        for (int a = 0; a < 3; ++a) {
            if (n[a] >= 0 && n[a] < d[a]) continue;
            if (p_.boundary[std::size_t(a)] != Boundary::Periodic) return false;
            n[a] = (n[a] + d[a]) % d[a];
        }
        return true;
    }

    struct Link {
        std::size_t site;
        int dir;
        float value;
    };
    const Problem& p_;
    std::vector<std::array<float, kQ>> src_, dst_;
    std::vector<std::int64_t> src_out_;
    std::vector<Link> in_links_;
    double last_absorbed_ = 0.0, last_escaped_ = 0.0, last_total_ = 0.0;
};

}  // namespace

std::unique_ptr<Kernel> make_naive_kernel(const Problem& p) { return std::make_unique<NaiveKernel>(p); }

}  // namespace fulgur::transport::lb
