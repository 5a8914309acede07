// fulgur::core — numerics where accumulation decides a result: compensated sums and relative L2.
#pragma once

#include <cmath>
#include <span>

namespace fulgur::core {

/// Neumaier compensated summation; use where a long accumulation decides a result.
struct CompensatedSum {
    double sum = 0.0, comp = 0.0;
    void add(double v) noexcept {
        const double t = sum + v;
        comp += (std::fabs(sum) >= std::fabs(v)) ? (sum - t) + v : (v - t) + sum;
        sum = t;
    }
    double value() const noexcept { return sum + comp; }
};

/// Relative L2 difference ||x - ref||_2 / ||ref||_2 of paired values, accumulated pair by
/// pair in compensated double sums; ||x - ref||_2 when the reference is all zero.
class RelativeL2 {
public:
    void add(double x, double ref) noexcept {
        const double d = x - ref;
        diff_.add(d * d);
        ref_.add(ref * ref);
    }
    double value() const noexcept {
        const double r = ref_.value();
        return std::sqrt(diff_.value() / (r > 0.0 ? r : 1.0));
    }
    /// ||ref||_2 of the pairs added so far.
    double reference_norm() const noexcept { return std::sqrt(ref_.value()); }

private:
    CompensatedSum diff_, ref_;
};

/// RelativeL2 of two arrays of the same length (element i of x against element i of ref).
double relative_l2(std::span<const float> x, std::span<const float> ref) noexcept;
double relative_l2(std::span<const double> x, std::span<const double> ref) noexcept;

}  // namespace fulgur::core
