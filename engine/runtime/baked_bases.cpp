// BakedBases (runtime.h, docs/runtime.md "Data layout"): a .fgb streamed light by light into
// one coefficient pool in the accumulation layout.
#include "runtime/detail/internal.h"

#include <cmath>
#include <utility>

namespace fulgur::runtime {

namespace {

// The file in the accumulation layout, streamed light by light (each block validated by
// FgbReader::read_light, as basis::load_fgb does), so the peak memory is the pool plus one
// light. Runs keep the file's order (by index in deflated files, by decreasing magnitude
// in plain ones): the order was measured to change the accumulation time by < 5% on the
// default storm (H in L1), and sorting costs load time.
std::unique_ptr<BakedBases::Impl> build_layout(basis::FgbReader& reader) {
    if (reader.partial())
        throw core::Error(reader.name(), "holds only lights [" + std::to_string(reader.light_begin()) + ", " +
                                             std::to_string(reader.light_end()) + ") of " +
                                             std::to_string(reader.metadata().light_count()) +
                                             " (a partial bake); merge the parts first");
    auto impl = std::make_unique<BakedBases::Impl>();
    BakedBases::Impl& b = *impl;
    b.meta = reader.metadata();
    b.bases_per_light = b.meta.bases();
    const std::size_t lights = b.meta.light_count(), runs = lights * b.bases_per_light;
    b.narrow = b.meta.cells() <= 65536;
    b.half = b.meta.compression.precision == basis::Precision::Float16;
    b.offset.assign(runs + 1, 0);
    b.gamma.assign(runs, 0.0);
    if (b.half) b.scale_exp.assign(runs, 0);
    // The exact coefficient count from the blocks' tables (CRC-checked, each count bounded
    // by the cells), reserved once: a deflated file gives no bound from its size.
    std::size_t bound = 0;
    for (std::uint32_t l = 0; l < lights; ++l) bound += std::size_t(reader.coefficient_count(l));
    if (b.narrow)
        b.index16.reserve(bound);
    else
        b.index32.reserve(bound);
    if (b.half)
        b.value16.reserve(bound);
    else
        b.value.reserve(bound);
    for (std::uint32_t l = 0; l < lights; ++l) {
        // Order::Any: each index occurs once per basis, so the accumulation's result does
        // not depend on the order within a basis (and the deflated files store them by index).
        const basis::CompressedLight cl = reader.read_light(l, basis::FgbReader::Order::Any);
        FULGUR_ASSERT(cl.directions.size() == b.bases_per_light, "FgbReader returned a light without all its bases");
        for (std::size_t k = 0; k < b.bases_per_light; ++k) {
            const std::size_t r = b.run(l, k);
            const basis::CompressedBasis& cb = cl.directions[k];
            b.offset[r] = b.values();
            b.gamma[r] = cb.gamma;
            // read_light has checked every index against the cell count.
            if (b.narrow)
                for (const std::uint32_t i : cb.index) b.index16.push_back(std::uint16_t(i));
            else
                b.index32.insert(b.index32.end(), cb.index.begin(), cb.index.end());
            if (b.half) {
                // Back to the file's half bits: exact (every stored value is half * 2^scale_exp).
                b.scale_exp[r] = cb.scale_exp;
                for (const float v : cb.value) b.value16.push_back(basis::float_to_half(std::ldexp(v, -cb.scale_exp)));
            } else {
                b.value.insert(b.value.end(), cb.value.begin(), cb.value.end());
            }
        }
    }
    b.offset[runs] = b.values();
    return impl;
}

}  // namespace

BakedBases::BakedBases(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BakedBases::BakedBases(BakedBases&&) noexcept = default;
BakedBases& BakedBases::operator=(BakedBases&&) noexcept = default;
BakedBases::~BakedBases() = default;

BakedBases BakedBases::load(const std::filesystem::path& fgb, const std::optional<basis::BakeKey>& expected) {
    basis::FgbReader reader(fgb);
    if (expected) reader.check_key(*expected);
    return BakedBases(build_layout(reader));
}

BakedBases BakedBases::load(const std::filesystem::path& fgb, const basis::FgbMetadata& expected) {
    basis::FgbReader reader(fgb);
    reader.check_metadata(expected);
    return BakedBases(build_layout(reader));
}

const core::GridGeometry& BakedBases::lighting() const noexcept { return impl_->meta.lighting; }
const std::vector<glm::dvec3>& BakedBases::directions() const noexcept { return impl_->meta.directions; }
const basis::VirtualLightGrid& BakedBases::lights() const noexcept { return impl_->meta.lights; }
const basis::FgbMetadata& BakedBases::metadata() const noexcept { return impl_->meta; }
bool BakedBases::has_multiple() const noexcept {
    return (impl_->meta.content & basis::FgbMetadata::kContentMultiple) != 0;
}
bool BakedBases::separate() const noexcept { return impl_->meta.components == 2; }
std::size_t BakedBases::coefficient_count() const noexcept { return std::size_t(impl_->offset.back()); }
std::size_t BakedBases::memory_bytes() const noexcept {
    const Impl& b = *impl_;
    return b.offset.size() * sizeof(std::uint64_t) + b.index16.size() * sizeof(std::uint16_t) +
           b.index32.size() * sizeof(std::uint32_t) + b.value.size() * sizeof(float) +
           b.value16.size() * sizeof(std::uint16_t) + b.scale_exp.size() * sizeof(std::int32_t) +
           b.gamma.size() * sizeof(double);
}

float BakedBases::Impl::value_at(std::size_t r, std::size_t k) const noexcept {
    const std::size_t q = std::size_t(offset[r]) + k;
    return half ? std::ldexp(half_to_float_fast(value16[q]), scale_exp[r]) : value[q];
}

}  // namespace fulgur::runtime
