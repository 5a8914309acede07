// Internal to fulgur::render: how a light group's light changed between two frames, for the
// temporal history (detail/temporal.h): by a factor, or in shape. No GL.
#pragma once

#include <cstddef>
#include <map>
#include <span>
#include <vector>

namespace fulgur::render::detail {

/// Whether a light group's values now are a multiple of those the history was made with: the
/// factor (`rescale`) while they are, `valid` false once they are not. The values are compared
/// by least squares: c = <now, then> / <then, then>, a multiple when |now - c then| <=
/// kTolerance |now| (the same light reconstructed at another intensity differs from a multiple
/// by float rounding, ~1e-7).
class ScaleTracker {
public:
    static constexpr double kTolerance = 1e-5;
    /// At most this many values are kept for the comparison (64 MB; a lighting grid of 32x32x24
    /// with 26 directions is 0.64 M): a larger group is never found a multiple of its previous
    /// values, and the history marches every pixel when it changes.
    static constexpr std::size_t kMaxValues = std::size_t(1) << 24;
    /// New values of the group, keyed (a direction of S; 0 for a single array); `fixed`: what
    /// must be identical for the values to be comparable (geometry). `replace`: keys not listed
    /// are dropped; else they keep their values (so the listed ones must keep theirs, c = 1),
    /// and a listed key never seen before is taken as consistent (another direction of the
    /// same light, as a moved camera asks for).
    void note(std::span<const float> fixed, const std::vector<int>& keys,
              const std::vector<std::span<const float>>& values, bool replace);
    /// The group is dark now: a multiple (0) of any history.
    void clear();
    /// The history was written with the current values.
    void written() {
        rescale_ = 1.0;
        valid_ = true;
    }
    void invalidate() { valid_ = false; }
    bool valid() const { return valid_; }
    /// No light in the group now.
    bool dark() const { return dark_; }
    double rescale() const { return rescale_; }

private:
    std::vector<float> fixed_;
    std::map<int, std::vector<float>> values_;
    bool dark_ = true;  ///< no light in the group (the history holds zero for it)
    bool valid_ = true;
    double rescale_ = 1.0;
};

}  // namespace fulgur::render::detail
