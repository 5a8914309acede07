// fulgur::basis — thresholding of Haar coefficients (Dobashi et al. 2007, section 6): which
// coefficients of a basis are kept, in what precision, and the paper's gamma.
// docs/basis.md sections 3-4 (thresholds, gamma and the ambient term).
#pragma once

#include "basis/haar.h"
#include "core/core.h"
#include "transport/transport.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace fulgur::basis {

enum class ThresholdMode : std::uint32_t {
    Absolute = 0,    ///< paper: drop |B| <= xi (units of the stored quantity)
    RelativeL2 = 1,  ///< drop |B| <= xi * ||B||_2 (the basis' own L2 norm): scale-free paper form
    Energy = 2,      ///< keep the fewest largest coefficients holding >= xi of ||B||^2, xi in [0, 1]
                     ///< (relative L2 error of the basis <= sqrt(1 - xi))
};
enum class Precision : std::uint32_t {
    Float32 = 0,
    Float16 = 1,  ///< binary16 with a per-basis power-of-two scale (docs/fgb-format.md)
};

/// How a .fgb block stores its kept coefficients (docs/fgb-format.md, "Block").
enum class Entropy : std::uint32_t {
    None = 0,     ///< fixed-width indices and values in magnitude order (fast to read)
    Deflate = 1,  ///< indices sorted and gap-coded (LEB128), values split into byte planes, the
                  ///< whole stream deflated (zlib): ~1.8x smaller for the same coefficients
};

/// "absolute" / "relative_l2" / "energy", "float32" / "float16", "none" / "deflate" (the
/// names used in scene files and reports).
std::string_view to_string(ThresholdMode m) noexcept;
std::string_view to_string(Precision p) noexcept;
std::string_view to_string(Entropy e) noexcept;

struct CompressionParams {
    ThresholdMode mode = ThresholdMode::Energy;
    double xi = 0.9999;  ///< energy kept: relative L2 error <= 1% per basis
    Precision precision = Precision::Float16;
    Decomposition decomposition = Decomposition::NonStandard;
    Entropy entropy = Entropy::Deflate;  ///< file encoding only: lossless, the values are the same
    bool operator==(const CompressionParams&) const = default;
};

/// Checks xi against the mode (finite, >= 0; <= 1 for Energy); throws core::Error naming
/// `where`.xi.
void validate(const CompressionParams& p, std::string_view where);

/// The kept coefficients of one basis (one light, one direction), in canonical order:
/// decreasing magnitude of the stored (rounded) value, ties by increasing index. Because of
/// that order, any prefix is the same basis compressed at a stricter threshold (see
/// retruncate()); and because it depends only on the stored values, a reader that gets the
/// coefficients in another order (Entropy::Deflate stores them by index) restores it exactly.
struct CompressedBasis {
    std::vector<std::uint32_t> index;  ///< position in the Haar coefficient array (x fastest)
    std::vector<float> value;          ///< the stored value (already rounded to the precision)
    double gamma = 0.0;                ///< paper's gamma: sqrt(sum of squares of the dropped coefficients)
    double norm = 0.0;                 ///< ||B||_2 of all coefficients before thresholding (= ||b||_2)
    int scale_exp = 0;                 ///< float16 only: value = half * 2^scale_exp; 0 for float32

    std::size_t size() const noexcept { return index.size(); }
    bool operator==(const CompressedBasis&) const = default;
};

/// All bases of one virtual light (every output direction, for every stored component;
/// FgbMetadata::basis_index gives the order): the unit of a bake job and of a file block.
struct CompressedLight {
    std::uint32_t light = 0;
    std::vector<CompressedBasis> directions;  ///< FgbMetadata::bases() entries
    std::size_t coefficient_count() const noexcept;
    bool operator==(const CompressedLight&) const = default;
};

/// Thresholds one basis given in the Haar domain (any length <= 2^32). Sums in double.
/// Values are rounded to the storage precision here, so the result is exactly what a file
/// stores. Throws core::Error (naming `where`) for non-finite coefficients or values that
/// overflow the precision.
CompressedBasis compress_coefficients(std::span<const double> coefficients, const CompressionParams& p,
                                      std::string_view where = "compress");

/// Forward Haar (in double) and compression of every direction of one light's field.
/// `plan` must have the field's dims and the params' decomposition. Throws core::Error for
/// non-finite samples.
CompressedLight compress_light(std::uint32_t light, const transport::SourceField& field, const CompressionParams& p,
                               HaarTransform<double>& plan);

/// Applies a stricter threshold to a stored basis without the original data: keeps the
/// leading coefficients that pass it (magnitude order makes this a prefix) and adds the
/// dropped ones to gamma. A looser threshold than the stored one changes nothing.
void retruncate(CompressedBasis& b, ThresholdMode mode, double xi);

/// Adds weight * B into a dense coefficient array (size = cells): the run time's Eq. 9.
void accumulate(const CompressedBasis& b, float weight, std::span<float> coefficients);
void accumulate(const CompressedBasis& b, double weight, std::span<double> coefficients);

/// Per-cell RMS reconstruction error of a basis over `cells` cells, gamma / sqrt(cells): the
/// consistent form of the paper's ambient term (Eq. 10), whose literal e_l * gamma per cell is
/// a bias sqrt(cells) times too large (docs/basis.md section 4). Radiance units.
inline double ambient_rms(const CompressedBasis& b, std::size_t cells) noexcept {
    return cells ? b.gamma / std::sqrt(double(cells)) : 0.0;
}

}  // namespace fulgur::basis
