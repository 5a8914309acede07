// The lattice the lattice-Boltzmann benchmarks step (bench_lb.cpp): n^3 sites of uniform
// medium (every row collides), a sun on the top face and a volume source at the centre.
#pragma once

#include "transport/detail/lb_solver.h"

namespace fulgur::bench {

transport::lb::Problem lb_problem(int n, transport::LbAbsorption absorption);

}  // namespace fulgur::bench
