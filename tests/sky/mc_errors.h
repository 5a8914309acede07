// The sun solve against Monte Carlo: relative L2 errors of S over chosen cells, the hybrid's
// single, multiple and total scattering and the total of Geist's injection (all orders on the
// lattice). Shared by the sun's Monte Carlo tests.
#pragma once

#include "sky/sky.h"

namespace fulgur::test {

struct SunMcErrors {
    core::RelativeL2 single, multiple, total, total_geist;
    /// Entry k (direction-major, as SourceField::data) of the hybrid solve `h`, Geist's
    /// injection `l` and the Monte Carlo reference `mc`.
    void add(const sky::LightField& h, const sky::LightField& l, const transport::MonteCarloResult& mc, std::size_t k) {
        single.add(h.single.data[k], mc.single.data[k]);
        multiple.add(h.multiple.data[k], mc.multiple.data[k]);
        const double ref = double(mc.single.data[k]) + double(mc.multiple.data[k]);
        total.add(double(h.single.data[k]) + double(h.multiple.data[k]), ref);
        total_geist.add(l.multiple.data[k], ref);
    }
};

}  // namespace fulgur::test
