// One virtual light's job (detail/light.h): its stored bases from a solve, compressed and
// encoded, with the compression error measured by the run time's inverse transform.
#include "bake/detail/light.h"

#include <algorithm>
#include <numbers>

namespace fulgur::bake {

namespace {

// Light l's stored bases from a solution: [single dirs][multiple dirs] when separate,
// else their sum (or the one part baked).
transport::SourceField stored_bases(const Plan& plan, solve::Solution&& sol) {
    const std::size_t cells = plan.lighting.cell_count(), nd = plan.output_directions.size();
    if (plan.components == 2) {
        std::vector<glm::dvec3> dirs = plan.output_directions;
        dirs.insert(dirs.end(), plan.output_directions.begin(), plan.output_directions.end());
        transport::SourceField out(plan.lighting, std::move(dirs));
        if (!sol.single.data.empty()) std::copy(sol.single.data.begin(), sol.single.data.end(), out.data.begin());
        if (!sol.multiple.data.empty())
            std::copy(sol.multiple.data.begin(), sol.multiple.data.end(),
                      out.data.begin() + std::ptrdiff_t(cells * nd));
        return out;
    }
    transport::SourceField out(plan.lighting, plan.output_directions);
    auto add = [&](const transport::SourceField& part) {
        for (std::size_t i = 0; i < out.data.size(); ++i) out.data[i] += part.data[i];
    };
    if (plan.single && !sol.single.data.empty()) add(sol.single);
    if (plan.multiple && !sol.multiple.data.empty()) add(sol.multiple);
    return out;
}

// Squared L2 norm of the stored field and of (reconstruction - field) over all bases of a
// light; reconstruction by the same inverse transform the run time uses (in double).
void compression_error(const basis::CompressedLight& c, const transport::SourceField& f,
                       basis::HaarTransform<double>& plan, double& ref2, double& err2) {
    const std::size_t cells = f.cells();
    std::vector<double> buf(cells);
    for (std::size_t m = 0; m < c.directions.size(); ++m) {
        std::fill(buf.begin(), buf.end(), 0.0);
        const basis::CompressedBasis& b = c.directions[m];
        basis::accumulate(b, 1.0, std::span<double>(buf));  // values are stored already scaled
        plan.inverse(buf);
        const std::span<const float> x = f.direction(m);
        core::CompensatedSum r, e;
        for (std::size_t i = 0; i < cells; ++i) {
            r.add(double(x[i]) * double(x[i]));
            const double d = buf[i] - double(x[i]);
            e.add(d * d);
        }
        ref2 += r.value();
        err2 += e.value();
    }
}

}  // namespace

transport::SourceField solve_light(const scene::Scene& s, const solve::Media& media, const Plan& plan,
                                   std::uint32_t light) {
    FULGUR_ASSERT(light < plan.lights.count(), "solve_light: light index out of range");
    const transport::PointSource src{plan.lights.position(light), 1.0};
    solve::SolveRequest rq;
    rq.single = true;
    rq.multiple = plan.multiple;
    solve::Solution sol = solve::solve(s, media, std::span(&src, 1), plan.output_directions, rq);
    return stored_bases(plan, std::move(sol));
}

namespace detail {

LightResult bake_one(const scene::Scene& s, const solve::Media& media, const Plan& plan,
                     basis::HaarTransform<double>& haar, std::uint32_t l) {
    LightResult out;
    const transport::PointSource src{plan.lights.position(l), 1.0};
    solve::SolveRequest rq;
    rq.single = true;
    rq.multiple = plan.multiple;
    rq.skip_below = s.drop_below;
    solve::Solution sol = solve::solve(s, media, std::span(&src, 1), plan.output_directions, rq);
    out.seconds_single = sol.seconds_single;
    out.seconds_multiple = sol.seconds_multiple;
    const double fraction = sol.first_scattered_power / (4.0 * std::numbers::pi);
    core::Stopwatch sw;
    basis::CompressedLight c;
    if (s.drop_below > 0.0 && fraction < s.drop_below) {
        c.light = l;
        c.directions.resize(plan.metadata.bases());
        out.dropped_fraction = fraction;
    } else {
        const int iterations = sol.iterations;
        const bool converged = sol.converged;
        const transport::SourceField f = stored_bases(plan, std::move(sol));
        c = basis::compress_light(l, f, s.compression, haar);
        compression_error(c, f, haar, out.ref2, out.err2);
        if (plan.multiple && plan.solver == "lattice_boltzmann") {
            out.iterations = iterations;
            out.converged = converged;
        }
    }
    out.coefficients = c.coefficient_count();
    out.seconds_compress = sw.seconds();
    out.block = basis::encode_block(c, plan.metadata);  // as the file stores it
    return out;
}

}  // namespace detail

}  // namespace fulgur::bake
