// The temporal history's tracker of a light group's changes (render/detail/scale_tracker.h):
// a multiple is found with its factor, float rounding stays a multiple, anything else is a
// change of shape, dark is a multiple of anything, and partial uploads keep the rest.
#include "render/detail/scale_tracker.h"

#include <doctest/doctest.h>

#include <cmath>
#include <vector>

using fulgur::render::detail::ScaleTracker;

namespace {

const std::vector<float> kGeometry = {0.0f, 0.0f, 0.0f, 125.0f, 32.0f, 32.0f, 24.0f, 26.0f};

// A light's values spanning orders of magnitude, as S does.
std::vector<float> light(std::size_t n = 1000, float scale = 1.0f) {
    std::vector<float> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = scale * float(std::exp(-double(i % 97) / 9.0) * (1.0 + double(i % 7)));
    return v;
}

std::vector<float> times(const std::vector<float>& v, double c) {
    std::vector<float> out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) out[i] = float(double(v[i]) * c);  // rounded to float
    return out;
}

void note(ScaleTracker& t, const std::vector<float>& v, int key = 0, bool replace = true) {
    t.note(kGeometry, {key}, {std::span<const float>(v)}, replace);
}

}  // namespace

TEST_CASE("scale tracker: a light at another intensity is a multiple; any other change is not") {
    ScaleTracker t;
    const std::vector<float> a = light();
    note(t, a);
    CHECK_FALSE(t.valid());  // light where the history (none yet) holds nothing
    t.written();
    // A decay: each frame's factor multiplies; float rounding of the products (~6e-8) stays a multiple.
    note(t, times(a, 0.7));
    note(t, times(a, 0.7 * 0.6));
    CHECK(t.valid());
    CHECK(t.rescale() == doctest::Approx(0.42).epsilon(1e-6));
    t.written();
    CHECK(t.rescale() == 1.0);

    // A change of shape: one value in a thousand moved by 1% of the whole's norm.
    std::vector<float> b = times(a, 0.42);
    double norm = 0.0;
    for (float x : b) norm += double(x) * double(x);
    b[500] += float(0.01 * std::sqrt(norm));
    note(t, b);
    CHECK_FALSE(t.valid());

    // Within the tolerance (1e-5 of the norm): still a multiple.
    ScaleTracker u;
    note(u, a);
    u.written();
    std::vector<float> c = a;
    norm = 0.0;
    for (float x : c) norm += double(x) * double(x);
    c[10] += float(2e-6 * std::sqrt(norm));
    note(u, c);
    CHECK(u.valid());
    CHECK(u.rescale() == doctest::Approx(1.0).epsilon(1e-5));
}

TEST_CASE("scale tracker: dark is zero times any history, light after dark is new") {
    ScaleTracker t;
    note(t, std::vector<float>(100, 0.0f));  // dark from the start: nothing to rescale
    CHECK(t.valid());
    const std::vector<float> a = light();
    note(t, a);
    CHECK_FALSE(t.valid());
    t.written();
    t.clear();  // the flash went dark
    CHECK(t.valid());
    CHECK(t.rescale() == 0.0);
    t.written();
    note(t, a);  // the same light again: the history holds zero for it
    CHECK_FALSE(t.valid());
}

TEST_CASE("scale tracker: another geometry, another size, partial uploads") {
    const std::vector<float> a = light(), a2 = light(1000, 3.0f);
    {
        ScaleTracker t;
        note(t, a);
        t.written();
        const std::vector<float> moved = {0.0f, 0.0f, 125.0f, 125.0f, 32.0f, 32.0f, 24.0f, 26.0f};
        t.note(moved, {0}, {std::span<const float>(a)}, true);
        CHECK_FALSE(t.valid());
    }
    {
        ScaleTracker t;
        note(t, a);
        t.written();
        note(t, light(999));  // another size of the same key: nothing to compare with
        CHECK_FALSE(t.valid());
    }
    {
        // Two directions; then only one of them uploaded, the other kept as it was.
        ScaleTracker t;
        t.note(kGeometry, {0, 1}, {std::span<const float>(a), std::span<const float>(a2)}, true);
        t.written();
        const std::vector<float> same = a2, doubled = times(a2, 2.0);
        note(t, same, 1, false);  // unchanged: a factor of 1 for both
        CHECK(t.valid());
        CHECK(t.rescale() == doctest::Approx(1.0));
        note(t, doubled, 1, false);  // direction 1 doubled, direction 0 kept: a change of shape
        CHECK_FALSE(t.valid());
    }
    {
        // A partial upload adding a direction never seen (a moved camera's): consistent.
        ScaleTracker t;
        note(t, a, 0);
        t.written();
        note(t, a2, 5, false);
        CHECK(t.valid());
    }
}

TEST_CASE("scale tracker: a group larger than the kept copy is never found a multiple") {
    ScaleTracker t;
    std::vector<float> big(ScaleTracker::kMaxValues + 1, 1.0f);
    note(t, big);
    t.written();
    for (float& x : big) x = 0.5f;
    note(t, big);
    CHECK_FALSE(t.valid());
}
