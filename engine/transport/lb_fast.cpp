// The fast kernel.
//
//  * Layout: structure of arrays, one float32 array per direction over a lattice padded by
//    one ghost site on every side (x fastest), so the inner loops have no boundary tests.
//  * Streaming: in place with the AA pattern (Bailey et al. 2009). Even steps read the 19
//    arriving densities of site x from its own slots A[q][x] and write the collided result
//    to the opposite slots A[opp q][x]; odd steps read A[opp q][x - c_q] and write
//    A[q][x + c_q]. Each memory location is read and written by one site only, so there is
//    one lattice in memory and no races between threads; per site update 19 floats are
//    read and 19 written (152 bytes; 144 in the physical model, which never uses the rest
//    direction).
//  * Collision: factored. Theta's scattering part takes 14 distinct values (P_ij depends
//    only on the classes of i, j and on c_i.c_j), so it acts on the sums and differences
//    of opposite pairs through a few aggregates (class totals, plane totals, two flux
//    vectors) instead of a 19x19 product: ~150 flops per site, vectorized over x
//    (#pragma omp simd). See "the factored collision in pair form" below.
//  * Empty rows (zero density, no source) only stream. Sources live in per-row blocks.
//  * Boundaries: open faces are handled per row right after the row's update (count the
//    outflow as escaped, place the inflow); periodic faces by a short pass after the rows
//    (copy across).
//  * Threads: rows (y, z) split statically over core::thread_count() threads; per-row
//    double accumulators summed in order, so results do not depend on the thread count.
#include "transport/detail/lb_solver.h"

#include <omp.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <new>
#include <utility>

namespace fulgur::transport::lb {

namespace {

// --- the factored collision in pair form --------------------------------------------------
//
// The 18 moving directions form 9 opposite pairs (q, q + 1), q odd: the axis pairs X, Y, Z
// and the diagonal pairs P7 (1,1,0), P9 (1,-1,0), P11 (1,0,1), P13 (1,0,-1), P15 (0,1,1),
// P17 (0,1,-1) (c of the odd member). Because P_ij depends only on the classes and on
// c_i.c_j, and P_{opp i, j} = P_{i, opp j}, the collision splits into an even part acting on
// the pair sums sigma_J = f_J+ + f_J- and an odd part acting on the differences
// delta_J = f_J+ - f_J-. With u = e f (e per class and site):
//   even:  Sigma_I = sum_J (P_{I+,J+} + P_{I+,J-}) sigma^u_J depends on |c_I.c_J| only, so it
//          is a combination of the class totals SA, SD, one plane (or axis) term and the
//          pair itself;
//   odd:   Delta_I = sum_J (P_{I+,J+} - P_{I+,J-}) delta^u_J is linear in c_I.c_J except for
//          the pair itself, so it needs the two "flux" vectors JA = sum_axis c_J delta^u_J and
//          JD = sum_diag c_J delta^u_J and the pair's own difference.
// Without the pair's own terms, H = Sigma / 2 and G = Delta / 2; then
//   out_{I+} = (1 - e + kp e) f_{I+} + km e f_{I-} + (H_I + G_I),
//   out_{I-} = (1 - e + kp e) f_{I-} + km e f_{I+} + (H_I - G_I):
// the unscattered part and the pair's own terms are applied per direction, so a small
// output next to a large opposite one (a beam's backward direction) is not the difference
// of two large numbers (H - G still cancels on what the other pairs scatter: the error is
// ~1e-7 of that, not of the output). About 150 vector instructions per 16 sites instead of
// ~370 for the class-sum form, and only a few aggregates live across the site update.
struct PairCoeffs {
    // (all on u = e f)
    // axis outputs: H_x = hA_pl Pl_yz + hA_SA SA + hA_SD SD, G_x = gA_JD JD_x, and the
    //   pair's own term: out_{+x} = (1 + kpA1 e) f_{+x} + kmA u_{-x} + H_x + G_x, where
    //   kpA1 = kpA - 1 (scattered back into the same direction, minus the extinguished unit)
    float kpA1, kmA, hA_pl, hA_SA, hA_SD, gA_JD;
    // diagonal outputs (plane xy, third axis z): H_I = hD_pl Pl_xy + hD_ax sigma_z
    //   + hD_SA SA + hD_SD SD, G_I = c_I . V, V = gD_JA JA + gD_JD JD, and the pair's own
    //   term as for the axes with kpD1, kmD
    float kpD1, kmD, hD_pl, hD_ax, hD_SA, hD_SD, gD_JA, gD_JD;
    float one_minus_albedo;
};

// The pair layout this kernel is written for (checked against the lattice table).
constexpr bool check_pair_layout() {
    constexpr int c[19][3] = {{0, 0, 0},  {1, 0, 0},   {-1, 0, 0},  {0, 1, 0},  {0, -1, 0}, {0, 0, 1},   {0, 0, -1},
                              {1, 1, 0},  {-1, -1, 0}, {1, -1, 0},  {-1, 1, 0}, {1, 0, 1},  {-1, 0, -1}, {1, 0, -1},
                              {-1, 0, 1}, {0, 1, 1},   {0, -1, -1}, {0, 1, -1}, {0, -1, 1}};
    for (int q = 0; q < kQ; ++q)
        if (kVelocity[std::size_t(q)].x != c[q][0] || kVelocity[std::size_t(q)].y != c[q][1] ||
            kVelocity[std::size_t(q)].z != c[q][2])
            return false;
    for (int q = 1; q < kQ; q += 2)
        if (opposite(q) != q + 1) return false;
    return true;
}
static_assert(check_pair_layout(), "the pair-form collision assumes this direction order");

PairCoeffs make_pair_coeffs(const DiscretePhase& phase, double albedo) {
    // Asserts the cubic structure (every entry equals its class representative).
    (void)factor_phase(phase, albedo);
    auto P = [&](int i, int j) { return albedo * phase.P[std::size_t(i)][std::size_t(j)]; };
    const double As = P(1, 1), Ao = P(1, 2), Ap = P(1, 3);
    const double ADp = P(1, 7), AD0 = P(1, 15), ADn = P(1, 8);
    const double DAp = P(7, 1), DA0 = P(7, 5), DAn = P(7, 2);
    const double DDs = P(7, 7), DDo = P(7, 8), DDp = P(7, 11), DD0 = P(7, 9), DDn = P(7, 12);
    PairCoeffs k{};
    k.hA_pl = float(0.5 * (2.0 * AD0 - ADp - ADn));
    k.hA_SA = float(Ap);
    k.hA_SD = float(0.5 * (ADp + ADn));
    k.gA_JD = float(0.5 * (ADp - ADn));
    k.hD_pl = float(0.5 * (2.0 * DD0 - DDp - DDn));
    k.hD_ax = float(0.5 * (2.0 * DA0 - DAp - DAn));
    k.hD_SA = float(0.5 * (DAp + DAn));
    k.hD_SD = float(0.5 * (DDp + DDn));
    k.gD_JA = float(0.5 * (DAp - DAn));
    k.gD_JD = float(0.5 * (DDp - DDn));
    // The pair's own terms (what the aggregates above do not already give): into the same
    // direction kp (stored as kp - 1, the float actually used), into the opposite one km.
    k.kpA1 = float(As - Ap - 1.0);
    k.kpD1 = float(DDs - DD0 - DDp + DDn - 1.0);
    const double kpA = double(k.kpA1) + 1.0, kpD = double(k.kpD1) + 1.0;
    // km absorbs the rounding of the others so that the scattered column sums, evaluated
    // exactly on the float coefficients, equal the double ones (albedo for the corrected
    // form; the published form keeps its own): an arriving axis or diagonal unit scatters
    // in total (the odd coefficients cancel in the sum over each pair)
    //   axis input:     kpA + kmA + 2 (3 hA_SA + 6 hD_SA + 2 hD_ax)            = colA
    //   diagonal input: kpD + kmD + 2 (2 hD_pl + 6 hD_SD + 3 hA_SD + hA_pl)    = colD
    // (no systematic energy drift in float32 kernels).
    const double colA = As + Ao + 4.0 * Ap + 4.0 * (DAp + DA0 + DAn);
    const double colD = 2.0 * (ADp + AD0 + ADn) + DDs + DDo + 4.0 * DDp + 2.0 * DD0 + 4.0 * DDn;
    k.kmA = float(colA - kpA - 2.0 * (3.0 * double(k.hA_SA) + 6.0 * double(k.hD_SA) + 2.0 * double(k.hD_ax)));
    k.kmD = float(colD - kpD -
                  2.0 * (2.0 * double(k.hD_pl) + 6.0 * double(k.hD_SD) + 3.0 * double(k.hA_SD) + double(k.hA_pl)));
    k.one_minus_albedo = float(1.0 - albedo);
    return k;
}

#if defined(__GNUC__)
#define FULGUR_INLINE inline __attribute__((always_inline))
#define FULGUR_LAMBDA_INLINE __attribute__((always_inline))
#else
#define FULGUR_INLINE inline
#define FULGUR_LAMBDA_INLINE
#endif

struct SiteResult {
    float extinguished, total;
};

// The whole update of one site: reads in[q][x] (q = 1..18; in[0] the rest density of the
// conservative model), writes out[q][x]; returns the extinguished total U = sum e_j f_j and
// the collided site total (float sum of the outputs). A function, so that the per-site
// values are the callee's locals (scalarized after inlining) rather than "omp simd" private
// arrays of the loop body, which GCC keeps in memory, lane by lane. Two passes: the pair
// sums and differences feed the aggregates, then each pair reloads its two densities (L1
// hits) and writes its two outputs, so that only the aggregates stay live across the
// passes (fewer register spills: ~14% faster than keeping all 18 values). Every direction
// index is a compile-time constant, so the loop over x vectorizes (a runtime loop over q
// with table lookups compiles to scalar code, ~10x slower).
template <bool Conservative, bool HasSource>
FULGUR_INLINE SiteResult update_site(const float* const* in, float* const* out, std::size_t x, float eA, float eD,
                                     const PairCoeffs& k, const float* src, std::size_t nx) {
    // pass 1: pair sums and differences of u = e f, and the aggregates
    auto ld = [&](auto Q) FULGUR_LAMBDA_INLINE { return in[Q][x]; };
    using std::integral_constant;
#define FULGUR_PAIR(name, q, e)                                  \
    float s##name, d##name;                                      \
    {                                                            \
        const float a = e * ld(integral_constant<int, q>{});     \
        const float b = e * ld(integral_constant<int, q + 1>{}); \
        s##name = a + b;                                         \
        d##name = a - b;                                         \
    }
    FULGUR_PAIR(x, 1, eA)
    FULGUR_PAIR(y, 3, eA)
    FULGUR_PAIR(z, 5, eA)
    FULGUR_PAIR(7, 7, eD)
    FULGUR_PAIR(9, 9, eD)
    FULGUR_PAIR(11, 11, eD)
    FULGUR_PAIR(13, 13, eD)
    FULGUR_PAIR(15, 15, eD)
    FULGUR_PAIR(17, 17, eD)
#undef FULGUR_PAIR
    const float SA = (sx + sy) + sz;
    const float Pxy = s7 + s9, Pxz = s11 + s13, Pyz = s15 + s17;
    const float SD = (Pxy + Pxz) + Pyz;
    const float JDx = (d7 + d9) + (d11 + d13);
    const float JDy = (d7 - d9) + (d15 + d17);
    const float JDz = (d11 - d13) + (d15 - d17);
    float CA = k.hA_SA * SA + k.hA_SD * SD;
    float CD = k.hD_SA * SA + k.hD_SD * SD;
    float rest = 0.0f;
    if constexpr (Conservative) {
        rest = in[0][x];
        CA += (1.0f / 12.0f) * rest;
        CD += (1.0f / 24.0f) * rest;
    }
    const float KA = k.kpA1 * eA + 1.0f, KD = k.kpD1 * eD + 1.0f;
    const float MA = k.kmA * eA, MD = k.kmD * eD;
    const float Vx = k.gD_JA * dx + k.gD_JD * JDx;
    const float Vy = k.gD_JA * dy + k.gD_JD * JDy;
    const float Vz = k.gD_JA * dz + k.gD_JD * JDz;
    float site = 0.0f;
    // pass 2: per pair, reload the two arriving densities and write the two outputs (the
    // pair's output slots are its own input slots, in both layouts)
    auto emit = [&](auto Q, float K, float M, float H, float G) FULGUR_LAMBDA_INLINE {
        constexpr int q = Q.value;
        const float fp = ld(integral_constant<int, q>{}), fm = ld(integral_constant<int, q + 1>{});
        float op = K * fp + (M * fm + (H + G));
        float om = K * fm + (M * fp + (H - G));
        if constexpr (HasSource) {
            op += src[std::size_t(q) * nx + x];
            om += src[std::size_t(q + 1) * nx + x];
        }
        site += op + om;
        out[q][x] = op;
        out[q + 1][x] = om;
    };
    emit(integral_constant<int, 1>{}, KA, MA, k.hA_pl * Pyz + CA, k.gA_JD * JDx);
    emit(integral_constant<int, 3>{}, KA, MA, k.hA_pl * Pxz + CA, k.gA_JD * JDy);
    emit(integral_constant<int, 5>{}, KA, MA, k.hA_pl * Pxy + CA, k.gA_JD * JDz);
    const float Cxy = k.hD_ax * sz + (k.hD_pl * Pxy + CD);
    const float Cxz = k.hD_ax * sy + (k.hD_pl * Pxz + CD);
    const float Cyz = k.hD_ax * sx + (k.hD_pl * Pyz + CD);
    emit(integral_constant<int, 7>{}, KD, MD, Cxy, Vx + Vy);
    emit(integral_constant<int, 9>{}, KD, MD, Cxy, Vx - Vy);
    emit(integral_constant<int, 11>{}, KD, MD, Cxz, Vx + Vz);
    emit(integral_constant<int, 13>{}, KD, MD, Cxz, Vx - Vz);
    emit(integral_constant<int, 15>{}, KD, MD, Cyz, Vy + Vz);
    emit(integral_constant<int, 17>{}, KD, MD, Cyz, Vy - Vz);
    const float U = SA + SD;
    if constexpr (Conservative) {
        float o0 = k.one_minus_albedo * U;
        if constexpr (HasSource) o0 += src[x];
        out[0][x] = o0;
        site += o0;
    }
    return {U, site};
}

// ptr[0] sits `lead` elements after a 64-byte boundary (all elements zeroed).
template <class T>
struct AlignedBuffer {
    T* ptr = nullptr;
    std::size_t n = 0;
    explicit AlignedBuffer(std::size_t count = 0) { resize(count); }
    AlignedBuffer(const AlignedBuffer&) = delete;
    AlignedBuffer& operator=(const AlignedBuffer&) = delete;
    ~AlignedBuffer() { std::free(raw_); }
    void resize(std::size_t count, std::size_t lead = 0) {
        std::free(raw_);
        raw_ = nullptr;
        ptr = nullptr;
        n = count;
        if (!count) return;
        const std::size_t bytes = (((count + lead) * sizeof(T) + 63) / 64) * 64;
        raw_ = static_cast<T*>(std::aligned_alloc(64, bytes));
        if (!raw_) throw std::bad_alloc();
        ptr = raw_ + lead;
        for (std::size_t i = 0; i < lead; ++i) raw_[i] = T{};
    }
    T& operator[](std::size_t i) noexcept { return ptr[i]; }
    const T& operator[](std::size_t i) const noexcept { return ptr[i]; }

private:
    T* raw_ = nullptr;
};

// Row-grouped (CSR) layout of (row, item) pairs given in row order: row r's items are
// out[begin[r], begin[r + 1]).
template <class T>
void group_by_row(std::size_t rows, const std::vector<std::pair<std::size_t, T>>& items,
                  std::vector<std::size_t>& begin, std::vector<T>& out) {
    begin.assign(rows + 1, 0);
    out.clear();
    out.reserve(items.size());
    for (const auto& [row, item] : items) {
        begin[row + 1]++;
        out.push_back(item);
    }
    for (std::size_t r = 0; r < rows; ++r) begin[r + 1] += begin[r];
}

class FastKernel final : public SlabKernel {
public:
    explicit FastKernel(const Problem& p) : p_(p), conservative_(p.absorption == LbAbsorption::Conservative) {
        const core::Int3 d = p.dims;
        // Rows padded to a multiple of 16 floats and the buffers offset by 15 floats, so that
        // every row's x = 0 starts a cache line: the even step's 512-bit loads and stores
        // are aligned (the odd step's for the directions with c_x = 0), and a row of 128
        // sites touches 8 lines per direction instead of 9.
        px_ = ((d.x + 2 + 15) / 16) * 16;
        py_ = d.y + 2;
        pz_ = d.z + 2;
        // Stride per direction: 64-byte aligned, and NOT a multiple of 4 KiB: the 19 arrays are
        // streamed at the same offset, and a power-of-two stride would map them all to the
        // same L1/L2 sets (conflict misses that cut throughput several times). 80 floats =
        // 5 cache lines of shift between consecutive directions.
        stride_ = ((std::size_t(px_) * std::size_t(py_) * std::size_t(pz_) + 1023) / 1024) * 1024 + 80;
        q0_ = conservative_ ? 0 : 1;
        data_.resize(stride_ * kQ, 15);
        ext_.resize(stride_ * 2, 15);
        // First touch by the threads that will work on the rows.
        const std::int64_t total = std::int64_t(stride_ * kQ);
#pragma omp parallel for schedule(static) num_threads(core::thread_count())
        for (std::int64_t i = 0; i < total; ++i) data_[std::size_t(i)] = 0.0f;
        for (std::size_t i = 0; i < stride_ * 2; ++i) ext_[i] = 0.0f;
        for (int q = 0; q < kQ; ++q) {
            const Velocity& c = kVelocity[std::size_t(q)];
            off_[q] = std::ptrdiff_t(c.x) +
                      std::ptrdiff_t(px_) * (std::ptrdiff_t(c.y) + std::ptrdiff_t(py_) * std::ptrdiff_t(c.z));
        }
        coeffs_ = make_pair_coeffs(p.phase, p.albedo);

        const std::size_t rows = std::size_t(d.y) * std::size_t(d.z);
        row_medium_.assign(rows, 0);
        row_source_.assign(rows, -1);
        row_sums_[0].assign(rows, RowSums{});
        row_sums_[1].assign(rows, RowSums{});
        for (int z = 0; z < d.z; ++z)
            for (int y = 0; y < d.y; ++y) {
                const std::size_t row = std::size_t(y) + std::size_t(d.y) * std::size_t(z);
                for (int x = 0; x < d.x; ++x) {
                    const std::size_t s = p.index(x, y, z), ps = pad(x, y, z);
                    ext_[ps] = p.ext_axis[s];
                    ext_[stride_ + ps] = p.ext_diag[s];
                    if (p.ext_axis[s] != 0.0f || p.ext_diag[s] != 0.0f) row_medium_[row] = 1;
                }
            }
        // Sources: one block of kQ * nx floats per row that has any.
        for (const auto& s : p.sources) {
            const core::Int3 c = unindex(s.site);
            const std::size_t row = std::size_t(c.y) + std::size_t(d.y) * std::size_t(c.z);
            if (row_source_[row] < 0) {
                row_source_[row] = std::int64_t(src_.size());
                src_.resize(src_.size() + std::size_t(kQ) * std::size_t(d.x), 0.0f);
                row_medium_[row] = 1;
            }
            for (int q = 0; q < kQ; ++q)
                src_[std::size_t(row_source_[row]) + std::size_t(q) * std::size_t(d.x) + std::size_t(c.x)] +=
                    s.out[std::size_t(q)];
        }
        build_boundary();
        // Initial state: the inflow has arrived (t = 0), natural layout.
        for (int z = 0; z < d.z; ++z)
            for (int y = 0; y < d.y; ++y) {
                const std::size_t row = std::size_t(y) + std::size_t(d.y) * std::size_t(z);
                for (std::size_t i = open_begin_[row]; i < open_begin_[row + 1]; ++i) {
                    slot(opposite(open_[i].q), pad(open_[i].x, y, z)) = open_[i].in;
                    inflow_sum_ += double(open_[i].in);
                }
            }
        last_total_ = inflow_sum_;
    }

    void step() override {
        const bool odd = (steps_ % 2) != 0;
        const core::Int3 d = p_.dims;
        const std::int64_t rows = std::int64_t(d.y) * std::int64_t(d.z);
#pragma omp parallel for schedule(static) num_threads(core::thread_count()) if (parallel())
        for (std::int64_t r = 0; r < rows; ++r) {
            if (odd)
                update_row<true>(r, 0);
            else
                update_row<false>(r, 0);
        }
        if (!pairs_.empty()) {
            if (odd)
                periodic_pass<true>();
            else
                periodic_pass<false>();
        }
        finish_step(0);
    }

    // Two steps in one sweep over z (only from an even step, without periodic faces: their
    // pass needs the whole even step first). The odd update of plane z needs the even update
    // of planes z - 1, z, z + 1 (it reads and writes slots in them), so each thread runs a
    // wavefront over its block of planes: even(z), then odd(z - 1), while plane z - 1's
    // lines are still in the last-level cache; the odd updates of a block's first and last
    // plane, which need the neighbouring block's even planes, wait for a barrier. Memory
    // traffic per two steps is then about that of one step. Every slot is read and written
    // by one site per step (AA pattern), so the deferred planes cannot conflict.
    void two_steps(StepResult& first, StepResult& second) override {
        const core::Int3 d = p_.dims;
        if (steps_ % 2 != 0 || !pairs_.empty() || d.z < 4) {
            Kernel::two_steps(first, second);
            return;
        }
        const int nz = d.z;
#pragma omp parallel num_threads(core::thread_count()) if (parallel())
        {
            const int t = omp_get_thread_num(), nt = omp_get_num_threads();
            const int z0 = int(std::int64_t(nz) * t / nt), z1 = int(std::int64_t(nz) * (t + 1) / nt);
            // odd(p) can run inside the block once even(p + 1) is done, unless it needs an
            // even plane of another block
            auto inside = [&](int p) { return (p == 0 || p - 1 >= z0) && (p + 1 == nz || p + 1 < z1); };
            for (int z = z0; z < z1; ++z) {
                even_plane(z);
                if (z - 1 >= z0 && inside(z - 1)) odd_plane(z - 1);
            }
            if (z1 > z0 && z1 == nz && inside(z1 - 1)) odd_plane(z1 - 1);
#pragma omp barrier
            if (z1 > z0) {
                if (!inside(z0)) odd_plane(z0);
                if (z1 - 1 != z0 && !inside(z1 - 1)) odd_plane(z1 - 1);
            }
        }
        finish_step(0);
        first = {last_absorbed_, last_escaped_, last_total_};
        finish_step(1);
        second = {last_absorbed_, last_escaped_, last_total_};
    }

    // Small lattices run on one thread: a parallel region per step costs more than the
    // work (and much more on a loaded machine, where a barrier can wait a time slice).
    bool parallel() const { return std::int64_t(p_.sites()) >= 65536 && core::thread_count() > 1; }

    // One row's update (collision or pure streaming, then its open boundary links); the
    // row's sums go to accumulator set `acc` (0 or 1: the two steps of two_steps()).
    template <bool Odd>
    void update_row(std::int64_t r, int acc) {
        const core::Int3 d = p_.dims;
        const int y = int(r % d.y), z = int(r / d.y);
        const std::size_t base = pad(0, y, z);
        float absorbed, total = 0.0f;
        const bool medium = row_medium_[std::size_t(r)] != 0;
        const float* src = row_source_[std::size_t(r)] >= 0 ? &src_[std::size_t(row_source_[std::size_t(r)])] : nullptr;
        if (!medium)
            absorbed = stream_row<Odd>(base, d.x, total);
        else if (conservative_)
            absorbed = row<Odd, true>(base, d.x, src, total);
        else
            absorbed = row<Odd, false>(base, d.x, src, total);
        RowSums& s = row_sums_[std::size_t(acc)][std::size_t(r)];
        s.absorbed = conservative_ ? 0.0 : double(absorbed) * (1.0 - p_.albedo);
        s.total = double(total);
        s.escaped = open_links<Odd>(r, base);
    }
    void even_plane(int z) {
        const std::int64_t ny = p_.dims.y;
        for (std::int64_t r = z * ny; r < (z + 1) * ny; ++r) update_row<false>(r, 0);
    }
    void odd_plane(int z) {
        const std::int64_t ny = p_.dims.y;
        for (std::int64_t r = z * ny; r < (z + 1) * ny; ++r) update_row<true>(r, 1);
    }
    // Sums the per-row accumulators in row order (the same for any thread count).
    void finish_step(int acc) {
        double a = 0.0, t = 0.0, e = 0.0;
        for (const RowSums& s : row_sums_[std::size_t(acc)]) {
            a += s.absorbed;
            t += s.total;
            e += s.escaped;
        }
        last_absorbed_ = a + p_.source_absorbed_per_step;
        last_escaped_ = e;
        last_total_ = t - last_escaped_ + inflow_sum_;
        ++steps_;
    }

    // --- a z-slab of a decomposed lattice (SlabKernel) ----------------------------------
    void update_planes(bool odd, int z0, int z1) override {
        const std::int64_t ny = p_.dims.y, r0 = std::int64_t(z0) * ny, r1 = std::int64_t(z1) * ny;
#pragma omp parallel for schedule(static) num_threads(core::thread_count()) if (parallel())
        for (std::int64_t r = r0; r < r1; ++r) {
            if (odd)
                update_row<true>(r, 0);
            else
                update_row<false>(r, 0);
        }
    }
    // The links of a face, plane position (x, y) and direction q, y then x then q: through
    // face `side` outgoing (c_z pointing out of the slab) or incoming, with x + c_x and
    // y + c_y inside (a link leaving through an x or y face too is an open link).
    template <class F>
    void face_links(int side, bool outgoing, F&& f) const {
        const core::Int3 d = p_.dims;
        const int cz = (side == 1) == outgoing ? 1 : -1;
        for (int y = 0; y < d.y; ++y)
            for (int x = 0; x < d.x; ++x)
                for (int q = 1; q < kQ; ++q) {
                    const Velocity& c = kVelocity[std::size_t(q)];
                    if (c.z != cz || x + c.x < 0 || x + c.x >= d.x || y + c.y < 0 || y + c.y >= d.y) continue;
                    f(x, y, q, c);
                }
    }
    // Face plane and ghost plane of a side.
    int face_z(int side) const { return side == 0 ? 0 : p_.dims.z - 1; }
    int ghost_z(int side) const { return side == 0 ? -1 : p_.dims.z; }
    void pack(bool odd, int side, std::vector<float>& out) const override {
        out.clear();
        const int zf = face_z(side), zg = ghost_z(side);
        // Even half: the collided density heading out, in the site's swapped slot. Odd half:
        // what the face plane streamed into the ghost plane.
        face_links(side, true, [&](int x, int y, int q, const Velocity& c) {
            out.push_back(odd ? data_[std::size_t(q) * stride_ + pad(x + c.x, y + c.y, zg)]
                              : data_[std::size_t(opposite(q)) * stride_ + pad(x, y, zf)]);
        });
    }
    void unpack(bool odd, int side, std::span<const float> in) override {
        const int zf = face_z(side), zg = ghost_z(side);
        std::size_t i = 0;
        // (x, y) are the neighbour's face-plane position: the same plane coordinates.
        face_links(side, false, [&](int x, int y, int q, const Velocity& c) {
            FULGUR_ASSERT(i < in.size(), "SlabKernel::unpack: fewer values than links");
            if (odd)
                slot(q, pad(x + c.x, y + c.y, zf)) = in[i++];
            else
                slot(opposite(q), pad(x, y, zg)) = in[i++];
        });
        FULGUR_ASSERT(i == in.size(), "SlabKernel::unpack: more values than links");
    }
    std::size_t halo_size() const override {
        std::size_t n = 0;
        face_links(0, true, [&](int, int, int, const Velocity&) { ++n; });
        return n;
    }
    Sums add_rows(Sums from) const override {
        for (const RowSums& s : row_sums_[0]) {
            from.absorbed += s.absorbed;
            from.total += s.total;
            from.escaped += s.escaped;
        }
        return from;
    }
    double add_inflow(double from) const override {
        for (const OpenLink& l : open_) from += double(l.in);
        return from;
    }
    void end_step(double absorbed, double escaped, double total) override {
        last_absorbed_ = absorbed;
        last_escaped_ = escaped;
        last_total_ = total;
        ++steps_;
    }

    double last_absorbed() const override { return last_absorbed_; }
    double last_escaped() const override { return last_escaped_; }
    double last_total() const override { return last_total_; }

    double stored() const override {
        // After the boundary pass every arriving density sits in exactly one interior slot.
        const core::Int3 d = p_.dims;
        double total = 0.0;
        for (int q = q0_; q < kQ; ++q)
            for (int z = 0; z < d.z; ++z)
                for (int y = 0; y < d.y; ++y) {
                    const float* a = &data_[std::size_t(q) * stride_ + pad(0, y, z)];
                    double row = 0.0;
                    for (int x = 0; x < d.x; ++x) row += double(a[x]);
                    total += row;
                }
        return total;
    }

    float arriving(std::size_t site, int q) const override {
        const core::Int3 c = unindex(site);
        const std::size_t ps = pad(c.x, c.y, c.z);
        if (q == 0) return conservative_ ? data_[ps] : 0.0f;
        if (steps_ % 2 == 0) return data_[std::size_t(q) * stride_ + ps];
        // Swapped layout: f_q(x) was written by x - c_q into A[opp q][x - c_q] (a ghost slot
        // holding the inflow or the periodic copy when x - c_q is outside).
        return data_[std::size_t(opposite(q)) * stride_ + std::size_t(std::ptrdiff_t(ps) - off_[q])];
    }

    void set_arriving(std::size_t site, int q, float v) override {
        FULGUR_ASSERT(steps_ == 0, "set_arriving only before the first step");
        FULGUR_ASSERT(q != 0 || conservative_, "the physical model has no rest density");
        const core::Int3 c = unindex(site);
        data_[std::size_t(q) * stride_ + pad(c.x, c.y, c.z)] = v;
    }

private:
    std::size_t pad(int x, int y, int z) const noexcept {
        return std::size_t(x + 1) + std::size_t(px_) * (std::size_t(y + 1) + std::size_t(py_) * std::size_t(z + 1));
    }
    core::Int3 unindex(std::size_t s) const noexcept {
        const core::Int3 d = p_.dims;
        return {int(s % std::size_t(d.x)), int((s / std::size_t(d.x)) % std::size_t(d.y)),
                int(s / (std::size_t(d.x) * std::size_t(d.y)))};
    }
    float& slot(int q, std::size_t ps) noexcept { return data_[std::size_t(q) * stride_ + ps]; }

    // The 19 read and 19 write pointers of a row (AA pattern, see the top of the file).
    template <bool Odd>
    void row_pointers(std::size_t base, const float** in, float** out) {
        float* A = data_.ptr;
        const std::size_t S = stride_;
        for (int q = 0; q < kQ; ++q) {
            if constexpr (!Odd) {
                in[q] = A + std::size_t(q) * S + base;
                out[q] = A + std::size_t(opposite(q)) * S + base;
            } else {
                in[q] = A + std::size_t(opposite(q)) * S + std::size_t(std::ptrdiff_t(base) - off_[q]);
                out[q] = A + std::size_t(q) * S + std::size_t(std::ptrdiff_t(base) + off_[q]);
            }
        }
    }

    // Pure streaming (no medium, no source) of one row: out_q = f_q, i.e. each opposite pair
    // swaps its two slots (both read and written by this site only), in one pass over x.
    template <bool Odd>
    float stream_row(std::size_t base, int nx, float& total) {
        const float* in[kQ];
        float* out[kQ];
        row_pointers<Odd>(base, in, out);
        float sum = 0.0f;
        const std::size_t n = std::size_t(nx);
#pragma omp simd reduction(+ : sum)
        for (std::size_t x = 0; x < n; ++x) {
            auto swap = [&](auto Q) FULGUR_LAMBDA_INLINE {
                constexpr int q = Q.value;
                const float a = in[q][x], b = in[q + 1][x];
                out[q][x] = a;
                out[q + 1][x] = b;
                sum += a + b;
            };
            using std::integral_constant;
            swap(integral_constant<int, 1>{});
            swap(integral_constant<int, 3>{});
            swap(integral_constant<int, 5>{});
            swap(integral_constant<int, 7>{});
            swap(integral_constant<int, 9>{});
            swap(integral_constant<int, 11>{});
            swap(integral_constant<int, 13>{});
            swap(integral_constant<int, 15>{});
            swap(integral_constant<int, 17>{});
        }
        if (conservative_) {  // the rest density stays
            const float* r0 = in[0];
#pragma omp simd reduction(+ : sum)
            for (std::size_t x = 0; x < n; ++x) sum += r0[x];
        }
        total = sum;
        return 0.0f;
    }

    template <bool Odd, bool Conservative>
    float row(std::size_t base, int nx, const float* src, float& total) {
        const std::size_t S = stride_;
        const float* __restrict eA = ext_.ptr + base;
        const float* __restrict eD = ext_.ptr + S + base;
        const float* in[kQ];
        float* out[kQ];
        row_pointers<Odd>(base, in, out);
        const PairCoeffs k = coeffs_;
        float absorbed = 0.0f, sum = 0.0f;
        const std::size_t n = std::size_t(nx);
        if (src) {
#pragma omp simd reduction(+ : absorbed, sum)
            for (std::size_t x = 0; x < n; ++x) {
                const SiteResult r = update_site<Conservative, true>(in, out, x, eA[x], eD[x], k, src, n);
                absorbed += r.extinguished;
                sum += r.total;
            }
        } else {
#pragma omp simd reduction(+ : absorbed, sum)
            for (std::size_t x = 0; x < n; ++x) {
                const SiteResult r = update_site<Conservative, false>(in, out, x, eA[x], eD[x], k, src, n);
                absorbed += r.extinguished;
                sum += r.total;
            }
        }
        total = sum;
        return absorbed;
    }

    // --- boundary links ----------------------------------------------------------------
    // Open faces, handled per row right after the row's update (its lines are still in
    // cache; no separate pass over the faces). After an even step the collided density
    // heading out (in the site's own swapped slot) escapes and the inflow takes its place
    // (the following even step reads it there), and the inflow is also written to the
    // ghost slot A[q][x + c_q] that the odd step reads. After an odd step the density the
    // update wrote to that ghost slot escapes. The ghost writes of the x faces are done by
    // the row that owns the ghost's cache line (the row at (y + c_y, z + c_z), whose update
    // touches that line anyway): done by the site's row, they would each fetch a cold line.
    // Every slot touched belongs to one link, so rows stay independent.
    struct OpenLink {
        std::int32_t x;  // site's x
        std::int32_t q;  // direction pointing out: x + c_q is outside
        float in;        // inflow arriving at x in direction opp(q)
    };
    struct GhostWrite {
        std::size_t index;  // in data_
        float in;
    };
    template <bool Odd>
    double open_links(std::int64_t r, std::size_t base) {
        float* A = data_.ptr;
        double escaped = 0.0;
        const std::size_t b = open_begin_[std::size_t(r)], e = open_begin_[std::size_t(r) + 1];
        for (std::size_t i = b; i < e; ++i) {
            const OpenLink& l = open_[i];
            const std::size_t site = base + std::size_t(l.x);
            if constexpr (!Odd) {
                float& own = A[std::size_t(opposite(l.q)) * stride_ + site];
                escaped += double(own);
                own = l.in;
            } else {
                escaped += double(A[ghost_off_[l.q] + site]);
            }
        }
        if constexpr (!Odd)
            for (std::size_t i = ghost_begin_[std::size_t(r)]; i < ghost_begin_[std::size_t(r) + 1]; ++i)
                A[ghosts_[i].index] = ghosts_[i].in;
        return escaped;
    }

    // Periodic faces: a pass after the rows (it copies between rows).
    struct Pair {
        std::size_t site;      // padded index of the interior site x
        int q;                 // direction pointing out: x + c_q is outside
        std::int64_t partner;  // padded index of wrap(x + c_q)
    };

    void build_boundary() {
        const core::Int3 d = p_.dims;
        const int dd[3] = {d.x, d.y, d.z};
        std::vector<float> inflow(p_.sites() * kQ, 0.0f);
        for (const auto& in : p_.inflow) inflow[in.site * kQ + std::size_t(in.dir)] += in.value;
        std::vector<std::pair<std::size_t, OpenLink>> open_rows;
        std::vector<std::pair<std::size_t, GhostWrite>> ghost_rows;
        for (int z = 0; z < d.z; ++z)
            for (int y = 0; y < d.y; ++y)
                for (int x = 0; x < d.x; ++x) {
                    if (x > 0 && y > 0 && z > 0 && x < d.x - 1 && y < d.y - 1 && z < d.z - 1) continue;
                    for (int q = 1; q < kQ; ++q) {
                        const Velocity& c = kVelocity[std::size_t(q)];
                        int n[3] = {x + c.x, y + c.y, z + c.z};
                        bool outside = false, open = false, halo = false;
                        for (int a = 0; a < 3; ++a) {
                            if (n[a] >= 0 && n[a] < dd[a]) continue;
                            outside = true;
                            if (p_.boundary[std::size_t(a)] == Boundary::Periodic)
                                n[a] = (n[a] + dd[a]) % dd[a];
                            else if (a == 2 && p_.halo_z[n[2] < 0 ? 0 : 1])
                                halo = true;
                            else
                                open = true;
                        }
                        if (!outside) continue;
                        if (halo && !open) continue;  // exchanged by the caller (pack, unpack)
                        if (open) {
                            const std::size_t row = std::size_t(y) + std::size_t(d.y) * std::size_t(z);
                            const float in = inflow[p_.index(x, y, z) * kQ + std::size_t(opposite(q))];
                            open_rows.push_back({row, {x, q, in}});
                            // the ghost's row, if it is an interior row (x faces), else the site's
                            const int gy = y + c.y, gz = z + c.z;
                            const bool interior_row = gy >= 0 && gy < d.y && gz >= 0 && gz < d.z;
                            const std::size_t grow =
                                interior_row ? std::size_t(gy) + std::size_t(d.y) * std::size_t(gz) : row;
                            ghost_rows.push_back(
                                {grow,
                                 {std::size_t(q) * stride_ + std::size_t(std::ptrdiff_t(pad(x, y, z)) + off_[q]), in}});
                            continue;
                        }
                        Pair pr{pad(x, y, z), q, std::int64_t(pad(n[0], n[1], n[2]))};
                        pairs_.push_back(pr);
                    }
                }
        // Open links: by row (already in row order: z, y, x, q).
        const std::size_t rows = std::size_t(d.y) * std::size_t(d.z);
        group_by_row(rows, open_rows, open_begin_, open_);
        std::stable_sort(ghost_rows.begin(), ghost_rows.end(),
                         [](const auto& a, const auto& b) { return a.first < b.first; });
        group_by_row(rows, ghost_rows, ghost_begin_, ghosts_);
        for (int q = 0; q < kQ; ++q) ghost_off_[q] = std::size_t(q) * stride_ + std::size_t(off_[q]);
        // Periodic pairs: grouped by direction, then by address: each group walks two
        // direction arrays in increasing order, and groups run in parallel (each copies to
        // its own slots).
        std::stable_sort(pairs_.begin(), pairs_.end(),
                         [](const Pair& a, const Pair& b) { return a.q != b.q ? a.q < b.q : a.site < b.site; });
        group_begin_.assign(kQ + 1, pairs_.size());
        for (std::size_t i = pairs_.size(); i-- > 0;) group_begin_[std::size_t(pairs_[i].q)] = i;
        for (int q = kQ - 1; q >= 0; --q)
            if (group_begin_[std::size_t(q)] > group_begin_[std::size_t(q + 1)])
                group_begin_[std::size_t(q)] = group_begin_[std::size_t(q + 1)];
    }

    template <bool Odd>
    void periodic_pass() {
        const bool parallel = pairs_.size() >= 16384 && core::thread_count() > 1;
#pragma omp parallel for schedule(dynamic, 1) num_threads(core::thread_count()) if (parallel)
        for (int q = 1; q < kQ; ++q) {
            const int o = opposite(q);
            for (std::size_t i = group_begin_[std::size_t(q)]; i < group_begin_[std::size_t(q + 1)]; ++i) {
                const Pair& b = pairs_[i];
                float& ghost = slot(q, std::size_t(std::ptrdiff_t(b.site) + off_[q]));
                if constexpr (!Odd)
                    ghost = slot(q, std::size_t(b.partner));
                else
                    slot(o, b.site) = slot(o, std::size_t(b.partner - off_[q]));
            }
        }
    }

    const Problem& p_;
    bool conservative_;
    int px_ = 0, py_ = 0, pz_ = 0, q0_ = 1;
    std::size_t stride_ = 0;
    std::ptrdiff_t off_[kQ] = {};
    AlignedBuffer<float> data_, ext_;
    PairCoeffs coeffs_{};
    std::vector<char> row_medium_;
    std::vector<std::int64_t> row_source_;
    std::vector<float> src_;
    struct RowSums {
        double absorbed = 0.0, total = 0.0, escaped = 0.0;
    };
    std::vector<RowSums> row_sums_[2];
    double inflow_sum_ = 0.0, last_total_ = 0.0;
    std::vector<OpenLink> open_;
    std::vector<std::size_t> open_begin_;
    std::vector<GhostWrite> ghosts_;
    std::vector<std::size_t> ghost_begin_;
    std::size_t ghost_off_[kQ] = {};
    std::vector<Pair> pairs_;
    std::vector<std::size_t> group_begin_;
    double last_absorbed_ = 0.0, last_escaped_ = 0.0;
};

}  // namespace

std::unique_ptr<Kernel> make_fast_kernel(const Problem& p) { return std::make_unique<FastKernel>(p); }

std::unique_ptr<SlabKernel> make_slab_kernel(const Problem& p) {
    FULGUR_ASSERT(p.boundary[0] == Boundary::Open && p.boundary[1] == Boundary::Open && p.boundary[2] == Boundary::Open,
                  "make_slab_kernel: open faces (halo_z marks those bordering another slab)");
    FULGUR_ASSERT(p.dims.z >= 2, "make_slab_kernel: a slab has at least 2 planes (face planes apart)");
    return std::make_unique<FastKernel>(p);
}

}  // namespace fulgur::transport::lb
