// The bake, the static light and the lattice over MPI ranks (engine/distributed), run by CTest
// under `mpirun -np 2`: every test case runs on every rank (they make the same collective
// calls); rank 0 checks the files. Scenes: the tiny golden-test scenes (32x32x16 density, 8x8x4
// lighting grid).
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include "bake/bake.h"
#include "distributed/detail/lattice.h"
#include "distributed/distributed.h"
#include "support/stop_hook.h"
#include "support/test_support.h"

#include <cstring>
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

namespace {

// Bit for bit: the same floats in the same places (memcmp, so -0 and +0 or two NaNs differ too).
bool same_bits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

bool any_positive(const std::vector<float>& v) {
    for (float x : v)
        if (x > 0.0f) return true;
    return false;
}

// The one-process field and the 2-rank one: every float and every figure of the solve equal.
void check_identical(const sky::LightField& one, const sky::LightField& two, bool lattice) {
    CHECK(same_bits(two.single.data, one.single.data));
    CHECK(same_bits(two.multiple.data, one.multiple.data));
    CHECK(two.iterations == one.iterations);
    CHECK(two.converged == one.converged);
    CHECK(two.injected_total == one.injected_total);
    CHECK(two.absorbed_total == one.absorbed_total);
    CHECK(two.escaped_total == one.escaped_total);
    CHECK(two.stored == one.stored);
    CHECK(two.first_scattered_power == one.first_scattered_power);
    if (lattice) CHECK(any_positive(two.multiple.data));  // the lattice ran: not two empty fields
}

// The day scene's static light, made small: fewer order-2 paths and an odd number of dome
// samples (the last round of the sky leaves one rank without a sample).
struct StaticCase {
    scene::Scene s = tiny("test_day_sun");
    core::Grid3<float> density = scene::make_density(s);
    solve::Media media = sky::static_media(s, density);
    std::vector<glm::dvec3> dirs = transport::output_directions(s.effective_directions());
    sky::SolveSettings settings() const {
        sky::SolveSettings st = sky::solve_settings(s, density);
        st.order2_paths = 20'000;
        st.sky_samples = 5;
        st.sky_paths = 0;  // the dome as directions (the sky test also takes it by Monte Carlo)
        return st;
    }
};

// `st` spread over the session's ranks, counting (in `slabs`) the lattices stepped in slabs.
sky::SolveSettings spread(sky::SolveSettings st, int& slabs) {
    st = distributed::static_light_settings(*g_session, st);
    REQUIRE(st.processes);
    REQUIRE(st.lattice.make_kernel);
    st.lattice.make_kernel = [make = st.lattice.make_kernel, &slabs](const transport::lb::Problem& p) {
        std::unique_ptr<transport::lb::Kernel> k = make(p);
        slabs += dynamic_cast<distributed::LatticeSlab*>(k.get()) != nullptr;
        return k;
    };
    return st;
}

}  // namespace

TEST_CASE("static light: the sun over 2 ranks is the one-process solve bit for bit (hybrid, order 2, lattice)") {
    REQUIRE(g_session->size() >= 2);
    const StaticCase c;
    REQUIRE(c.media.transport.density.dims().z >= 2 * g_session->size());  // a lattice in slabs
    const transport::DirectionalSource sun{c.s.sun->direction, 1.0};
    struct Variant {
        const char* name;
        sky::Method method;
        int exact_orders;
    };
    for (const Variant v : {Variant{"hybrid, lattice for orders >= 2", sky::Method::Hybrid, 1},
                            Variant{"hybrid, order 2 by Monte Carlo", sky::Method::Hybrid, 2},
                            Variant{"Geist's injection", sky::Method::Lattice, 1}}) {
        INFO(v.name);
        sky::SolveSettings st = c.settings();
        st.method = v.method;
        st.exact_orders = v.exact_orders;
        const sky::LightField one = sky::solve_directional(c.media, std::span(&sun, 1), c.dirs, st);
        int slabs = 0;
        const sky::LightField two = sky::solve_directional(c.media, std::span(&sun, 1), c.dirs, spread(st, slabs));
        CHECK(slabs == 1);
        check_identical(one, two, true);
        if (v.method == sky::Method::Hybrid) CHECK(any_positive(two.single.data));
    }
}

TEST_CASE("static light: the sky over 2 ranks is the one-process solve bit for bit (two ends, and uniform)") {
    REQUIRE(g_session->size() >= 2);
    const StaticCase c;
    // The dome as 5 directions dealt out round by round, and by its own Monte Carlo (one basis
    // per rank).
    for (const std::uint64_t paths : {std::uint64_t(0), std::uint64_t(20'000)})
        for (const bool uniform : {false, true}) {
            sky::SolveSettings st = c.settings();
            st.sky_paths = paths;
            INFO("uniform " << uniform << ", sky paths " << paths);
            const sky::SkyField one = sky::solve_sky(c.media, uniform, c.dirs, st);
            int slabs = 0;
            const sky::SkyField two = sky::solve_sky(c.media, uniform, c.dirs, spread(st, slabs));
            CHECK(slabs == (uniform ? 1 : 2));
            if (uniform) {
                check_identical(one.uniform, two.uniform, true);
            } else {
                check_identical(one.zenith, two.zenith, true);
                check_identical(one.horizon, two.horizon, true);
            }
        }
}

TEST_CASE("static light: load_or_solve over 2 ranks, rank 0 writes the cache; a fresh file stops every rank") {
    const distributed::Session& session = *g_session;
    REQUIRE(session.size() >= 2);
    const StaticCase c;
    bake::PlanOptions po;
    po.estimate = false;
    sky::ScenePlan plan = sky::plan_scene(c.s, c.density, po);
    REQUIRE(plan.sun);
    REQUIRE(plan.sky);
    const sky::SolveSettings alone = c.settings();
    int slabs = 0;
    plan.settings = spread(alone, slabs);
    const fs::path dir = dir_of("distributed_static_light");
    const sky::CacheOptions cache{true, dir};
    std::vector<std::string> said;
    const auto say = [&](const std::string& m) { said.push_back(m); };

    const sky::StaticLight first = sky::load_or_solve(c.s, c.density, c.media, plan, cache, say);
    CHECK(slabs == 3);  // the sun's lattice and the sky's two, each over both ranks
    // Every rank holds the solved light, the one-process solve's bits.
    const transport::DirectionalSource sun{c.s.sun->direction, 1.0};
    REQUIRE(first.sun);
    REQUIRE(first.sky);
    check_identical(sky::solve_directional(c.media, std::span(&sun, 1), c.dirs, alone), *first.sun, true);
    const sky::SkyField sky1 = sky::solve_sky(c.media, plan.sky_uniform, c.dirs, alone);
    CHECK(same_bits(first.sky->zenith.multiple.data, sky1.zenith.multiple.data));
    CHECK(same_bits(first.sky->horizon.single.data, sky1.horizon.single.data));
    if (session.rank() == 0) {
        CHECK(fs::exists(dir / "test_day_sun.sun.fgl"));
        CHECK(fs::exists(dir / "test_day_sun.sky.fgl"));
        CHECK(said.size() == 2);  // rank 0 speaks
    } else {
        CHECK(said.empty());
    }

    // Again: rank 0 finds both files fresh and no rank starts a solve (no lattice is made).
    said.clear();
    const sky::StaticLight again = sky::load_or_solve(c.s, c.density, c.media, plan, cache, say);
    CHECK(slabs == 3);
    if (session.rank() == 0) {
        REQUIRE(again.sun);
        REQUIRE(again.sky);
        CHECK(same_bits(again.sun->multiple.data, first.sun->multiple.data));  // the file holds the bits
        CHECK(same_bits(again.sky->zenith.single.data, first.sky->zenith.single.data));
        REQUIRE(said.size() == 2);
        CHECK(said[0].find("read from") != std::string::npos);
    } else {
        CHECK_FALSE(again.sun);  // read on rank 0 only
        CHECK_FALSE(again.sky);
    }
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
