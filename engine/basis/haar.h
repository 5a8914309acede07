// fulgur::basis — the orthonormal 3D Haar transform of a dense grid, any size per axis.
// docs/basis.md section 2 describes the 1D "unbalanced" scheme, the two 3D decompositions
// and the factored arithmetic that keeps float32 accurate.
#pragma once

#include "core/core.h"

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace fulgur::basis {

/// How the 1D transform is applied in 3D (docs/basis.md compares them):
enum class Decomposition : std::uint32_t {
    Standard = 0,     ///< full 1D transform along x, then y, then z (tensor-product basis)
    NonStandard = 1,  ///< one level along x, y, z, then recurse on the low octant (default: fewer
                      ///< coefficients at 1% error, half the arithmetic)
};

/// "standard" / "nonstandard" (the names used in scene files and reports).
std::string_view to_string(Decomposition d) noexcept;

namespace detail {

// The transform's plan per axis (internal to HaarTransform and haar.cpp).
/// One level of the 1D plan on the m current approximations.
template <class T>
struct HaarLevel {
    int m = 0;      ///< length transformed at this level
    int pairs = 0;  ///< floor(m/2)
    int half = 0;   ///< ceil(m/2): approximations that go on to the next level
    /// When m is even, the last pair's step: x0 = u00 a + u01 d, x1 = u10 a + u11 d.
    T u00 = T(1), u01 = T(1), u10 = T(1), u11 = T(-1);
};
template <class T>
struct HaarAxis {
    std::vector<HaarLevel<T>> levels;  ///< finest first; J = levels.size()
    std::vector<int> t;                ///< t[l]: factor exponent of the last node entering level l (t[0] = 0)
    std::vector<int> detail_level;     ///< per position: the level whose detail it is (INT_MAX for 0)
    std::vector<int> exponent;         ///< standard decomposition: e of k^e in P per position
    /// Runs of equal exponent along the axis: [begin, end) and e.
    std::vector<int> run_begin, run_end, run_exponent;
};

}  // namespace detail

/// Orthonormal 3D Haar transform of a dense grid (x fastest), any size per axis (1 included).
/// Exact for constants on any length: coefficient 0 is sum(x) / sqrt(n) in both
/// decompositions, every other basis function has zero mean, Parseval holds exactly.
/// Coefficient layout per axis: approximations first, details coarse to fine; index
/// i + nx (j + ny k). The inverse runs as U P (P: one scale k^e per coefficient, U: plain
/// sums and differences), the forward as P U^T. The object owns its plan and scratch: forward()/inverse() do not
/// allocate. One object per thread (calls mutate the scratch).
template <class T>
class HaarTransform {
public:
    explicit HaarTransform(core::Int3 dims, Decomposition d = Decomposition::NonStandard);

    const core::Int3& dims() const noexcept { return dims_; }
    Decomposition decomposition() const noexcept { return decomposition_; }
    std::size_t size() const noexcept { return dims_.volume(); }

    /// Samples -> coefficients, in place. data.size() must equal size().
    void forward(std::span<T> data);
    /// Coefficients -> samples, in place. data.size() must equal size().
    void inverse(std::span<T> data);

private:
    using Axis = detail::HaarAxis<T>;
    void scale(T* d) const noexcept;

    core::Int3 dims_;
    Decomposition decomposition_;
    Axis axes_[3];
    std::vector<T> powk_;    ///< k^e (k = 1/sqrt 2), e = 0 .. sum of the axes' depths
    std::vector<T> factor_;  ///< non-standard: P per coefficient
    std::vector<T> scratch_;
};

extern template class HaarTransform<float>;
extern template class HaarTransform<double>;

}  // namespace fulgur::basis
