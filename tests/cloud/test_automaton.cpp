// Dobashi et al. 2000's automaton: the growth rules against a direct transcription, the
// neighbourhood's shape, the extinction and supply probabilities, thread independence, and
// the space-time smoothing.
#include "cloud/detail/automaton.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

using namespace fulgur;
using cloud::detail::Automaton;

namespace {

constexpr std::uint8_t H = Automaton::kHum, A = Automaton::kAct, C = Automaton::kCld;

std::vector<std::uint8_t> full_weights(core::Int3 d, std::uint8_t w = 255) {
    return std::vector<std::uint8_t>(d.volume(), w);
}

// The growth rules written out literally from the paper, on an unpadded grid with "false"
// outside.
std::vector<std::uint8_t> reference_growth(core::Int3 d, const std::vector<std::uint8_t>& s) {
    auto at = [&](int i, int j, int k) -> std::uint8_t {
        if (i < 0 || j < 0 || k < 0 || i >= d.x || j >= d.y || k >= d.z) return 0;
        return s[std::size_t(i) + std::size_t(d.x) * (std::size_t(j) + std::size_t(d.y) * std::size_t(k))];
    };
    auto act = [&](int i, int j, int k) { return (at(i, j, k) & A) != 0; };
    std::vector<std::uint8_t> out(s.size());
    for (int k = 0; k < d.z; ++k)
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i) {
                const bool f_act = act(i + 1, j, k) || act(i, j + 1, k) || act(i, j, k + 1) || act(i - 1, j, k) ||
                                   act(i, j - 1, k) || act(i, j, k - 1) || act(i - 2, j, k) || act(i + 2, j, k) ||
                                   act(i, j - 2, k) || act(i, j + 2, k) || act(i, j, k - 2);
                const std::uint8_t c = at(i, j, k);
                const bool hum = c & H, a = c & A, cld = c & C;
                const bool hum_n = hum && !a, cld_n = cld || a, act_n = !a && hum && f_act;
                out[std::size_t(i) + std::size_t(d.x) * (std::size_t(j) + std::size_t(d.y) * std::size_t(k))] =
                    std::uint8_t((hum_n ? H : 0) | (act_n ? A : 0) | (cld_n ? C : 0));
            }
    return out;
}

std::vector<std::uint8_t> state_of(const Automaton& a) {
    const core::Int3 d = a.dims();
    std::vector<std::uint8_t> s;
    for (int k = 0; k < d.z; ++k)
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i) s.push_back(a.get(i, j, k));
    return s;
}

}  // namespace

TEST_CASE("growth rules match a literal transcription of the paper's rules") {
    // Full seed weight and zero probabilities: no extinction (p_ext (1 - W) = 0) and no
    // supply, so a step is the deterministic growth rule alone. 11x7x9 and a random start
    // exercise the grid boundaries (treated as "false") on every side.
    const core::Int3 d{11, 7, 9};
    Automaton a(d, full_weights(d), {0.0, 0.0, 0.0}, 1);
    core::Rng rng(42);
    std::vector<std::uint8_t> s(d.volume());
    for (int k = 0; k < d.z; ++k)
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i) {
                const auto bits = std::uint8_t(rng.uniform_below(8));
                a.set(i, j, k, bits);
                s[std::size_t(i) + std::size_t(d.x) * (std::size_t(j) + std::size_t(d.y) * std::size_t(k))] = bits;
            }
    for (int step = 0; step < 6; ++step) {
        CAPTURE(step);
        s = reference_growth(d, s);
        a.step();
        REQUIRE(state_of(a) == s);
    }
}

TEST_CASE("activation spreads to the 11-cell neighbourhood: two cells up, one down") {
    const core::Int3 d{9, 9, 9};
    Automaton a(d, full_weights(d), {0.0, 0.0, 0.0}, 1);
    for (int k = 0; k < d.z; ++k)
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i) a.set(i, j, k, H);
    a.set(4, 4, 4, A);
    a.step();
    int activated = 0;
    for (int k = 0; k < d.z; ++k)
        for (int j = 0; j < d.y; ++j)
            for (int i = 0; i < d.x; ++i) activated += (a.get(i, j, k) & A) ? 1 : 0;
    CHECK(activated == 11);
    for (int o : {-2, -1, 1, 2}) {
        CHECK((a.get(4 + o, 4, 4) & A) != 0);
        CHECK((a.get(4, 4 + o, 4) & A) != 0);
    }
    CHECK((a.get(4, 4, 5) & A) != 0);
    CHECK((a.get(4, 4, 6) & A) != 0);  // (i, j, k-2) is a neighbour: cells two above see it
    CHECK((a.get(4, 4, 3) & A) != 0);
    CHECK((a.get(4, 4, 2) & A) == 0);  // (i, j, k+2) is not: clouds grow up faster than down
    // The active cell itself: act -> cld, loses its activation, keeps no vapour.
    CHECK(a.get(4, 4, 4) == C);
    // A newly activated cell still holds its vapour; the next step turns both into cloud.
    CHECK(a.get(5, 4, 4) == (H | A));
    a.step();
    CHECK(a.get(5, 4, 4) == C);
}

TEST_CASE("extinction and supply happen with the probabilities the seed weight gives") {
    const core::Int3 d{32, 32, 32};
    const double n = double(d.volume());
    auto fraction = [&](const Automaton& a, std::uint8_t bit) {
        std::size_t c = 0;
        for (int k = 0; k < d.z; ++k)
            for (int j = 0; j < d.y; ++j)
                for (int i = 0; i < d.x; ++i) c += (a.get(i, j, k) & bit) ? 1 : 0;
        return double(c) / n;
    };
    // 5 binomial standard errors: a false alarm has probability < 1e-6.
    auto tol = [&](double p) { return 5.0 * std::sqrt(p * (1.0 - p) / n); };

    SUBCASE("extinction: p_ext (1 - W)") {
        const std::uint8_t w = 102;  // W = 0.4
        Automaton a(d, full_weights(d, w), {0.5, 0.0, 0.0}, 7);
        for (int k = 0; k < d.z; ++k)
            for (int j = 0; j < d.y; ++j)
                for (int i = 0; i < d.x; ++i) a.set(i, j, k, C);
        a.step();
        const double expected = 1.0 - 0.5 * (1.0 - w / 255.0);
        CHECK(std::fabs(fraction(a, C) - expected) < tol(expected));
    }
    SUBCASE("supply: p_hum W and p_act W") {
        const std::uint8_t w = 191;  // W = 0.75
        Automaton a(d, full_weights(d, w), {0.0, 0.4, 0.2}, 9);
        a.step();
        const double ph = 0.4 * w / 255.0, pa = 0.2 * w / 255.0;
        CHECK(std::fabs(fraction(a, H) - ph) < tol(ph));
        CHECK(std::fabs(fraction(a, A) - pa) < tol(pa));
        CHECK(fraction(a, C) == 0.0);  // cloud only follows activation, one step later
    }
}

TEST_CASE("cells with seed weight 0 stay empty, whatever their neighbours do") {
    const core::Int3 d{8, 8, 8};
    std::vector<std::uint8_t> w = full_weights(d);
    for (int j = 0; j < d.y; ++j)
        for (int i = 0; i < d.x; ++i) w[std::size_t(i) + 8 * std::size_t(j) + 64 * 4] = 0;  // layer k = 4
    Automaton a(d, w, {0.3, 1.0, 1.0}, 3);  // saturating supply everywhere else
    for (int s = 0; s < 10; ++s) a.step();
    std::size_t nonzero = 0;
    for (int j = 0; j < d.y; ++j)
        for (int i = 0; i < d.x; ++i) nonzero += a.get(i, j, 4) != 0 ? 1 : 0;
    CHECK(nonzero == 0);
    CHECK(a.cloud_cells() > 0);
}

TEST_CASE("the automaton's result does not depend on the thread count") {
    const core::Int3 d{40, 24, 30};
    std::vector<std::uint8_t> w(d.volume());
    core::Rng rng(5);
    for (auto& v : w) v = std::uint8_t(rng.uniform_below(256));
    auto run = [&](int threads) {
        const int saved = core::thread_count();
        core::set_thread_count(threads);
        Automaton a(d, w, {0.2, 0.2, 0.05}, 11);
        a.init_vapour();
        std::vector<std::uint8_t> counts(d.volume(), 0);
        for (int s = 0; s < 12; ++s) a.step(counts.data());
        core::set_thread_count(saved);
        return std::pair{state_of(a), counts};
    };
    const auto one = run(1);
    CHECK(one == run(2));
    CHECK(one == run(5));
    std::size_t counted = 0;
    for (auto c : one.second) counted += c;
    CHECK(counted > 0);
}

TEST_CASE("smoothing: constant in, constant out; flat base; mass conserved; gain clamps") {
    const core::Int3 d{16, 16, 20};
    const int window = 4, base = 5;
    SUBCASE("a full cloud above the base stays full, up to the base layer itself") {
        std::vector<std::uint8_t> counts(d.volume(), 0);
        for (std::size_t q = std::size_t(base) * 256; q < counts.size(); ++q) counts[q] = window;
        const std::vector<float> rho = cloud::detail::smooth_density(d, counts, window, 2, base, 1.0);
        // Interior column (2 voxels from the x/y faces: beyond the kernel's reach) at the
        // base layer and above: exactly 1 up to float rounding of the normalized weights.
        for (int k = base; k < d.z - 2; ++k) CHECK(rho[8 + 16 * 8 + 256 * std::size_t(k)] == test::rel(1.0, 1e-6));
        for (int k = 0; k < base; ++k) CHECK(rho[8 + 16 * 8 + 256 * std::size_t(k)] == 0.0f);
    }
    SUBCASE("an isolated impulse spreads but keeps its mass, gain scales and clamps") {
        std::vector<std::uint8_t> counts(d.volume(), 0);
        counts[8 + 16 * 8 + 256 * 10] = 2;  // 2 of 4 steps cloudy: 0.5
        std::vector<float> rho = cloud::detail::smooth_density(d, counts, window, 2, 0, 1.0);
        double sum = 0.0;
        for (float v : rho) sum += v;
        CHECK(sum == test::rel(0.5, 1e-6));  // normalized kernel, away from all faces
        CHECK(rho[8 + 16 * 8 + 256 * 10] < 0.5f);
        CHECK(rho[9 + 16 * 8 + 256 * 10] > 0.0f);
        rho = cloud::detail::smooth_density(d, counts, window, 0, 0, 3.0);
        CHECK(rho[8 + 16 * 8 + 256 * 10] == 1.0f);  // 0.5 * 3 clamped to 1
    }
}
