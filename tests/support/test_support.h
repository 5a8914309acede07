// Shared helpers for Fulgur's tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <ostream>
#include <span>
#include <string>
#include <vector>

namespace fulgur::test {

/// Whether this program is built with AddressSanitizer (gcc's macro, clang's feature test).
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

/// The repository root (for content/, shaders/, tests/ data).
std::filesystem::path source_dir();

/// A fresh, empty directory under the build tree for this test's files.
std::filesystem::path scratch_dir(const std::string& name);

/// A directory under the build tree for artefacts a test caches across runs (bakes, sun/sky
/// caches), keyed by the code version: <output>/<name>/<hash of the engine's and shaders'
/// sources>. Made on first use; the versions made by other code are deleted, so an artefact
/// is never reused by a build whose solvers or shaders differ from the one that made it.
std::filesystem::path code_cache_dir(const std::string& name);

/// core::relative_l2 (||x - ref||_2 / ||ref||_2, the absolute L2 difference when ref is all
/// zero); sizes must match (a failed REQUIRE otherwise).
double relative_l2(std::span<const float> x, std::span<const float> ref);

/// A relative comparison, CHECK(x == test::rel(expected, tolerance)):
///   x == expected, or |x - expected| <= tolerance * max(|x|, |expected|).
/// doctest::Approx(e).epsilon(t) compares |x - e| < t * (1 + max(|x|, |e|)) instead: below 1
/// its tolerance is absolute, so on a quantity like S (1e-6 W m^-2 sr^-1) it passes anything.
/// A quantity expected to be 0 is checked against an absolute bound (|x| < b), with its reason.
struct Rel {
    double expected = 0.0, tolerance = 0.0;
};
inline Rel rel(double expected, double tolerance) { return {expected, tolerance}; }
inline bool operator==(double x, const Rel& r) {
    return x == r.expected || std::fabs(x - r.expected) <= r.tolerance * std::max(std::fabs(x), std::fabs(r.expected));
}
inline bool operator==(const Rel& r, double x) { return x == r; }
inline bool operator!=(double x, const Rel& r) { return !(x == r); }
inline bool operator!=(const Rel& r, double x) { return !(x == r); }
inline std::ostream& operator<<(std::ostream& os, const Rel& r) {
    return os << r.expected << " (relative " << r.tolerance << ")";
}

/// Names of the temporaries and lock files ("*.tmp", "*.lock") in `dir`: a writer that
/// failed or finished leaves none (core::AtomicFile).
std::vector<std::string> temporaries(const std::filesystem::path& dir);

/// `text` with the first occurrence of `from` replaced by `to` (a failed REQUIRE when absent):
/// for scene variants written as edits of one scene text.
std::string replace_once(std::string text, const std::string& from, const std::string& to);

/// The seed of this run's randomized (fuzz-style) loops: FULGUR_TEST_SEED when set (to replay
/// a failure), otherwise a fresh random one; printed once per process so any failure can be
/// replayed.
std::uint64_t run_seed();

/// Writes `text` to `path` (overwriting).
void write_text(const std::filesystem::path& path, const std::string& text);

/// The whole of the file at `path`, byte for byte (empty when it cannot be opened).
std::string read_text(const std::filesystem::path& path);

}  // namespace fulgur::test
