#include "core/core.h"

namespace fulgur::core {

namespace {
template <class T>
double relative_l2_of(std::span<const T> x, std::span<const T> ref) noexcept {
    FULGUR_ASSERT(x.size() == ref.size(), "relative_l2: arrays of different lengths");
    RelativeL2 e;
    for (std::size_t i = 0; i < x.size(); ++i) e.add(double(x[i]), double(ref[i]));
    return e.value();
}
}  // namespace

double relative_l2(std::span<const float> x, std::span<const float> ref) noexcept { return relative_l2_of(x, ref); }
double relative_l2(std::span<const double> x, std::span<const double> ref) noexcept { return relative_l2_of(x, ref); }

}  // namespace fulgur::core
