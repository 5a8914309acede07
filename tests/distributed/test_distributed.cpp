// The bake over MPI ranks (engine/distributed), run by CTest under `mpirun -np 2`: every test
// case runs on every rank (they make the same collective calls); rank 0 checks the files.
// Scenes: the tiny golden-test scenes (32x32x16 density, 8x8x4 lighting grid).
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include "bake/bake.h"
#include "distributed/detail/lattice.h"
#include "distributed/distributed.h"
#include "support/stop_hook.h"
#include "support/test_support.h"

#include <fstream>
#include <iterator>
#include <sstream>

using namespace fulgur;
namespace fs = std::filesystem;

namespace {

const distributed::Session* g_session = nullptr;

scene::Scene tiny(const std::string& name) {
    return scene::load_scene(test::source_dir() / "tests/apps/scenes" / (name + ".json"));
}

std::vector<std::uint8_t> read_bytes(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), {}};
}

bake::Plan plan_of(const scene::Scene& s, const core::Grid3<float>& d) {
    bake::PlanOptions o;
    o.estimate = false;
    o.threads = 1;
    bake::Plan p = bake::make_plan(s, d, o);
    p.threads = 1;
    return p;
}

// Rank 0's directory for a test's files (the others write none).
fs::path dir_of(const std::string& name) {
    return g_session->rank() == 0 ? test::scratch_dir(name) : fs::path("/nonexistent-rank-dir");
}

}  // namespace

TEST_CASE("distributed bake: 2 ranks write the bytes of the 1-process bake") {
    const distributed::Session& session = *g_session;
    REQUIRE(session.size() >= 2);  // run by CTest under mpirun -np 2
    const scene::Scene s = tiny("test_aniso_ms_cg");
    const core::Grid3<float> d = scene::make_density(s);
    const bake::Plan plan = plan_of(s, d);
    const fs::path dir = dir_of("distributed_bake");
    if (session.rank() == 0) bake::bake(s, d, plan, dir / "one.fgb");
    (void)session.broadcast(0);  // the other ranks wait (polling) while rank 0 bakes alone

    std::size_t last = 0;
    bake::BakeOptions o;
    o.chunk = 3;  // several chunks per rank on this small grid
    const std::optional<bake::Report> r =
        distributed::bake(session, s, d, plan, dir / "two.fgb", o, [&](std::size_t done, std::size_t total, double) {
            CHECK(total == plan.lights.count());
            last = done;
        });
    CHECK(r.has_value() == (session.rank() == 0));
    if (session.rank() == 0) {
        CHECK(last == plan.lights.count());  // progress over all ranks on rank 0
        CHECK(r->lights == plan.lights.count());
        CHECK(read_bytes(dir / "two.fgb") == read_bytes(dir / "one.fgb"));
    }
}

TEST_CASE("distributed bake: stopped after some lights, resumed on 2 ranks, the same bytes") {
    const distributed::Session& session = *g_session;
    REQUIRE(session.size() >= 2);
    const scene::Scene s = tiny("test_iso_ss_ic");
    const core::Grid3<float> d = scene::make_density(s);
    const bake::Plan plan = plan_of(s, d);
    const fs::path dir = dir_of("distributed_resume");
    if (session.rank() == 0) bake::bake(s, d, plan, dir / "one.fgb");
    (void)session.broadcast(0);

    const fs::path out = dir / "two.fgb";
    std::size_t kept = 0;
    bake::BakeOptions o = test::stop_after(out, 6, kept);
    // Rank 0 stops; it releases the other ranks first, so every rank returns.
    if (session.rank() == 0) {
        CHECK_THROWS_AS(distributed::bake(session, s, d, plan, out, o), test::Stop);
    } else {
        CHECK_FALSE(distributed::bake(session, s, d, plan, out, o).has_value());
    }
    if (session.rank() == 0) {
        CHECK(kept >= 6);
        CHECK(kept < plan.lights.count());
        CHECK_FALSE(fs::exists(out));
    }
    o.on_checkpoint = {};
    const std::optional<bake::Report> r = distributed::bake(session, s, d, plan, out, o);
    if (session.rank() == 0) {
        CHECK(r->lights_resumed >= 6);
        CHECK(read_bytes(out) == read_bytes(dir / "one.fgb"));
        CHECK_FALSE(fs::exists(o.checkpoint));
    }
}

namespace {

// A 20 x 18 x 16 lattice with a varying medium (so rows differ: empty rows only stream), an
// inflow on the top face and on one side face, and two volume sources, one on a slab face.
transport::lb::Problem test_lattice() {
    using namespace transport;
    using namespace transport::lb;
    const core::Int3 d{20, 18, 16};
    const Medium m{0.02, 0.95, 0.6};
    Problem p = Problem::uniform(d, site_coefficients(m, 25.0, 0.5), corrected_phase(0.6), LbAbsorption::Physical);
    for (int z = 0; z < d.z; ++z)
        for (int y = 0; y < d.y; ++y)
            for (int x = 0; x < d.x; ++x) {
                const std::size_t s = p.index(x, y, z);
                const float f = (x + 2 * y + 3 * z) % 7 == 0 ? 0.0f : float(0.3 + 0.1 * ((x * y + z) % 5));
                p.ext_axis[s] *= f;
                p.ext_diag[s] *= f;
            }
    for (int y = 0; y < d.y; ++y)
        for (int x = 0; x < d.x; ++x) {
            p.inflow.push_back({p.index(x, y, d.z - 1), 6, 1.0f});  // down through the top face
            p.inflow_per_step += 1.0;
        }
    for (int z = 0; z < d.z; ++z)
        for (int y = 0; y < d.y; ++y) {
            p.inflow.push_back({p.index(0, y, z), 11, 0.25f});  // (1, 0, 1) through the x = 0 face
            p.inflow_per_step += 0.25;
        }
    std::array<double, kQ> e{};
    for (int q = 1; q < kQ; ++q) e[std::size_t(q)] = weight(q);
    p.add_source(p.index(10, 9, 8), e, site_coefficients(m, 25.0, 0.5));  // on the 2-rank slab face
    p.add_source(p.index(3, 4, 2), e, site_coefficients(m, 25.0, 0.5));
    return p;
}

}  // namespace

TEST_CASE("distributed lattice: z-slabs on 2 ranks step bit-identically to the one-process fast kernel") {
    const distributed::Session& session = *g_session;
    REQUIRE(session.size() >= 2);
    const transport::lb::Problem p = test_lattice();
    // Steady state by the same convergence test, the figures of the whole lattice on every rank.
    transport::lb::Simulation one(p, transport::LbKernel::Fast);
    const bool one_converged = one.run(1e-6, 400);
    auto slab = std::make_unique<distributed::LatticeSlab>(session, p);
    distributed::LatticeSlab* s = slab.get();
    CHECK(s->z_end() - s->z_begin() == p.dims.z / session.size());
    transport::lb::Simulation two(p, std::move(slab));
    const bool two_converged = two.run(1e-6, 400);
    CHECK(two_converged == one_converged);
    CHECK(two.steps() == one.steps());
    // Bit for bit: the same float operations per site, the sums in the same order.
    CHECK(two.kernel().last_total() == one.kernel().last_total());
    CHECK(two.absorbed_total() == one.absorbed_total());
    CHECK(two.escaped_total() == one.escaped_total());
    const std::vector<float> all = s->gather();
    if (session.rank() == 0) {
        REQUIRE(all.size() == p.sites() * transport::lb::kQ);
        std::size_t differ = 0;
        for (std::size_t site = 0; site < p.sites(); ++site)
            for (int q = 0; q < transport::lb::kQ; ++q)
                differ += all[site * transport::lb::kQ + std::size_t(q)] != one.kernel().arriving(site, q);
        CHECK(differ == 0);
    }
    MESSAGE("steps " << one.steps() << ", converged " << one_converged);
}

int main(int argc, char** argv) {
    const distributed::Session session(argc, argv);
    g_session = &session;
    doctest::Context context(argc, argv);
    std::ostringstream quiet;
    if (session.rank() != 0) context.setCout(&quiet);  // one report, rank 0's
    const int failed = context.run();
    if (session.rank() != 0 && failed) std::fputs(quiet.str().c_str(), stderr);
    return failed;
}
