// The .fgb file: bit-exact round trips, partial files and merge, stale detection, and a
// loader that rejects every truncation and corruption without crashing (this test also
// runs under AddressSanitizer + UndefinedBehaviorSanitizer: the asan preset).
#include "bake_fixture.h"
#include "basis/basis.h"
#include "basis/detail/internal.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <zlib.h>

#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <thread>

using namespace fulgur;
using basis::FgbReader;

namespace {

std::vector<std::uint8_t> slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}
void spit(const std::filesystem::path& p, const std::vector<std::uint8_t>& b) {
    std::ofstream(p, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

basis::FgbMetadata small_meta(basis::Precision prec, basis::Entropy entropy) {
    basis::FgbMetadata m = test::small_metadata(prec);
    m.compression.entropy = entropy;
    return m;
}

std::filesystem::path write_small(const std::filesystem::path& path, basis::Precision prec,
                                  basis::Entropy entropy = basis::Entropy::Deflate) {
    const basis::FgbMetadata m = small_meta(prec, entropy);
    basis::FgbWriter w(path, m);
    for (std::uint32_t l = 0; l < m.light_count(); ++l) w.add(test::small_light(m, l));
    w.finish();
    return path;
}

basis::BakedBasis load_bytes(std::vector<std::uint8_t> b, const basis::BakeKey* key = nullptr) {
    FgbReader r(std::move(b), "mem.fgb");
    basis::LoadOptions o;
    o.expected_key = key;
    return basis::load_fgb(r, o);
}

template <class T>
T get(const std::vector<std::uint8_t>& b, std::size_t at) {
    T v;
    std::memcpy(&v, b.data() + at, sizeof(T));
    return v;
}
template <class T>
void put(std::vector<std::uint8_t>& b, std::size_t at, T v) {
    std::memcpy(b.data() + at, &v, sizeof(T));
}

// Recomputes the block CRCs in the index and the header CRC using the layout of the
// pristine file, so a corruption gets past the checksums to the structural validation.
void fix_crcs(std::vector<std::uint8_t>& b, const std::vector<std::uint8_t>& pristine) {
    using namespace basis::fgb;
    const auto index_offset = get<std::uint64_t>(pristine, kOffIndexOffset);
    const auto blocks_offset = get<std::uint64_t>(pristine, kOffBlocksOffset);
    const auto n = get<std::uint64_t>(pristine, kOffIndexSize) / kIndexEntrySize;
    for (std::uint64_t i = 0; i < n; ++i) {
        const std::size_t e = std::size_t(index_offset + i * kIndexEntrySize);
        const auto off = get<std::uint64_t>(pristine, e), size = get<std::uint64_t>(pristine, e + 8);
        put(b, e + kEntryOffCrc, basis::crc32_of(std::span(b).subspan(std::size_t(off), std::size_t(size))));
    }
    put(b, kOffHeaderCrc, basis::fgb::header_crc(b, blocks_offset));
}

}  // namespace

TEST_CASE(".fgb round trip is bit-exact, float32 and float16, plain and deflated, 2- and 4-byte indices") {
    const auto dir = test::scratch_dir("fgb_roundtrip");
    for (const auto entropy : {basis::Entropy::None, basis::Entropy::Deflate})
        for (const auto prec : {basis::Precision::Float32, basis::Precision::Float16}) {
            INFO(basis::to_string(prec) << ", " << basis::to_string(entropy));
            const auto path = write_small(dir / "a.fgb", prec, entropy);
            const basis::FgbMetadata m = small_meta(prec, entropy);
            const basis::BakedBasis b = basis::load_fgb(path);
            CHECK(b.meta == m);
            REQUIRE(b.lights.size() == m.light_count());
            for (std::uint32_t l = 0; l < m.light_count(); ++l) CHECK(b.lights[l] == test::small_light(m, l));
            CHECK(b.lights[5].coefficient_count() == 0);  // the dropped light survives as an empty block
            // Writing what was loaded gives the same bytes.
            {
                basis::FgbWriter w(dir / "b.fgb", b.meta);
                for (const auto& l : b.lights) w.add(l);
                w.finish();
            }
            CHECK(slurp(path) == slurp(dir / "b.fgb"));
            CHECK(test::temporaries(dir).empty());
        }
    // Two components (single and multiple stored apart): 2 x 3 bases per light.
    {
        const basis::FgbMetadata m2 = test::small_metadata(basis::Precision::Float16, {5, 4, 3}, 3, 2);
        REQUIRE(m2.bases() == 6);
        {
            basis::FgbWriter w(dir / "c2.fgb", m2);
            for (std::uint32_t l = 0; l < m2.light_count(); ++l) w.add(test::small_light(m2, l));
            w.finish();
        }
        const basis::BakedBasis b2 = basis::load_fgb(dir / "c2.fgb");
        CHECK(b2.meta == m2);
        for (std::uint32_t l = 0; l < m2.light_count(); ++l) CHECK(b2.lights[l] == test::small_light(m2, l));
        // A file and a metadata record that disagree on components are errors, not misreads.
        basis::FgbMetadata bad = m2;
        bad.content = basis::FgbMetadata::kContentSingle;
        CHECK_THROWS_AS(basis::validate(bad, "meta"), core::Error);
    }
    // More than 65536 cells: 4-byte indices.
    basis::FgbMetadata big = test::small_metadata(basis::Precision::Float16, {41, 40, 40}, 1);
    CHECK(big.index_bytes() == 4);
    big.compression = {basis::ThresholdMode::Absolute, 0.0, basis::Precision::Float16};  // keep all 65600
    big.lights.x = {0.0};
    big.lights.y = {0.0};
    big.lights.z = {0.0};
    big.lights.base_layer = 0;
    const basis::CompressedLight l0 = test::small_light(big, 0);
    for (const auto entropy : {basis::Entropy::None, basis::Entropy::Deflate}) {
        big.compression.entropy = entropy;
        {
            basis::FgbWriter w(dir / "big.fgb", big);
            w.add(l0);
            w.finish();
        }
        const basis::BakedBasis bb = basis::load_fgb(dir / "big.fgb");
        CHECK(bb.lights[0] == l0);
        bool high_index = false;
        for (std::uint32_t i : bb.lights[0].directions[0].index) high_index |= i > 65535;
        CHECK(high_index);
    }
}

TEST_CASE("blocks from independent jobs: any order, several threads, partial files and merge") {
    const auto dir = test::scratch_dir("fgb_merge");
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float16);
    const auto complete = write_small(dir / "complete.fgb", basis::Precision::Float16);

    // Two threads adding lights in scrambled order: the same content.
    {
        basis::FgbWriter w(dir / "threads.fgb", m);
        auto job = [&](int t) {
            for (std::uint32_t l = 7 - std::uint32_t(t); l < 8; l -= 2) w.add(test::small_light(m, l));
        };
        std::thread a(job, 0), b(job, 1);
        a.join();
        b.join();
        w.finish();
    }
    CHECK(basis::load_fgb(dir / "threads.fgb").lights == basis::load_fgb(complete).lights);

    // Three bake jobs write partial files; the merge only concatenates, checks and indexes.
    const std::pair<std::uint32_t, std::uint32_t> ranges[] = {{3, 5}, {0, 3}, {5, 8}};
    std::vector<std::filesystem::path> parts;
    for (auto [a, b] : ranges) {
        parts.push_back(dir / ("part" + std::to_string(a) + ".fgb"));
        basis::FgbWriter w(parts.back(), m, a, b);
        for (std::uint32_t l = b; l-- > a;) w.add(test::small_light(m, l));
        w.finish();
        FgbReader r(parts.back());
        CHECK(r.partial());
        CHECK_THROWS_WITH_AS(basis::load_fgb(parts.back()), doctest::Contains("partial bake"), core::Error);
    }
    basis::merge_fgb(dir / "merged.fgb", parts);
    CHECK(slurp(dir / "merged.fgb") == slurp(complete));  // blocks copied verbatim, in light order

    // Merging two parts into a bigger part, then with the rest.
    const std::vector<std::filesystem::path> first = {parts[1], parts[0]};
    basis::merge_fgb(dir / "p0_5.fgb", first);
    CHECK(FgbReader(dir / "p0_5.fgb").light_end() == 5);
    const std::vector<std::filesystem::path> second = {dir / "p0_5.fgb", parts[2]};
    basis::merge_fgb(dir / "merged2.fgb", second);
    CHECK(slurp(dir / "merged2.fgb") == slurp(complete));

    // Overlap, gap, different bakes.
    const std::vector<std::filesystem::path> overlap = {parts[1], dir / "p0_5.fgb"};
    CHECK_THROWS_WITH_AS(basis::merge_fgb(dir / "x.fgb", overlap), doctest::Contains("overlap"), core::Error);
    const std::vector<std::filesystem::path> gap = {parts[1], parts[2]};
    CHECK_THROWS_WITH_AS(basis::merge_fgb(dir / "x.fgb", gap), doctest::Contains("gap"), core::Error);
    basis::FgbMetadata other = m;
    other.key = basis::BakeKey::from_description("something else");
    {
        basis::FgbWriter w(dir / "other.fgb", other, 3, 5);
        for (std::uint32_t l = 3; l < 5; ++l) w.add(test::small_light(other, l));
        w.finish();
    }
    const std::vector<std::filesystem::path> mixed = {parts[1], dir / "other.fgb", parts[2]};
    CHECK_THROWS_WITH_AS(basis::merge_fgb(dir / "x.fgb", mixed), doctest::Contains("metadata"), core::Error);
    CHECK_FALSE(std::filesystem::exists(dir / "x.fgb"));
    CHECK(test::temporaries(dir).empty());
}

TEST_CASE("writer misuse by data: missing, duplicate and out-of-range lights") {
    const auto dir = test::scratch_dir("fgb_writer");
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float32);
    {
        basis::FgbWriter w(dir / "w.fgb", m);
        w.add(test::small_light(m, 0));
        CHECK_THROWS_WITH_AS(w.add(test::small_light(m, 0)), doctest::Contains("added twice"), core::Error);
        CHECK_THROWS_WITH_AS(w.finish(), doctest::Contains("first: light 1"), core::Error);
    }
    CHECK_FALSE(std::filesystem::exists(dir / "w.fgb"));  // never looks finished
    CHECK(test::temporaries(dir).empty());                // and leaves nothing behind
    basis::FgbWriter w(dir / "p.fgb", m, 2, 4);
    CHECK_THROWS_WITH_AS(w.add(test::small_light(m, 4)), doctest::Contains("outside this file's range [2, 4)"),
                         core::Error);
    CHECK_THROWS_AS(basis::FgbWriter(dir / "q.fgb", m, 4, 4), core::Error);
    CHECK_THROWS_AS(basis::FgbWriter(dir / "q.fgb", m, 0, 9), core::Error);
}

TEST_CASE("a stale file is detected and the difference explained") {
    const auto dir = test::scratch_dir("fgb_stale");
    const auto path = write_small(dir / "s.fgb", basis::Precision::Float16);
    const basis::FgbMetadata m = test::small_metadata(basis::Precision::Float16);
    basis::LoadOptions o;
    o.expected_key = &m.key;
    CHECK_NOTHROW(basis::load_fgb(path, o));
    std::string desc = m.key.description;
    desc.replace(desc.find("albedo=0.99"), 11, "albedo=0.90");
    const basis::BakeKey changed = basis::BakeKey::from_description(desc);
    CHECK(changed.hash != m.key.hash);
    o.expected_key = &changed;
    CHECK_THROWS_WITH_AS(basis::load_fgb(path, o), doctest::Contains("stale bake"), core::Error);
    CHECK_THROWS_WITH_AS(
        basis::load_fgb(path, o),
        doctest::Contains("line 3: the file has \"medium.albedo=0.99\", the scene has \"medium.albedo=0.90\""),
        core::Error);
    basis::BakeKey same_text = m.key;
    same_text.hash ^= 1;  // caller-supplied hash differs, description equal
    o.expected_key = &same_text;
    CHECK_THROWS_WITH_AS(basis::load_fgb(path, o), doctest::Contains("only the hashes differ"), core::Error);
}

TEST_CASE("specific damage is named: magic, version, endianness, size, CRCs") {
    const auto dir = test::scratch_dir("fgb_damage");
    const std::vector<std::uint8_t> good = slurp(write_small(dir / "g.fgb", basis::Precision::Float16));
    using namespace basis::fgb;
    auto expect = [&](std::vector<std::uint8_t> b, const char* needle) {
        CHECK_THROWS_WITH_AS(load_bytes(std::move(b)), doctest::Contains(needle), core::Error);
    };
    {
        auto b = good;
        b[1] = 'X';
        expect(b, "header.magic: not a Fulgur");
    }
    {
        auto b = good;
        b[4] = '\n';  // "\r\n" -> "\n\n": a text-mode transfer
        expect(b, "text-mode");
    }
    {
        auto b = good;
        put<std::uint32_t>(b, kOffVersion, 1);  // a file of the previous format (no components field)
        expect(b, "mem.fgb (byte 8): header.version: format version 1");
    }
    {
        auto b = good;
        put<std::uint32_t>(b, kOffEndian, 0x04030201u);
        expect(b, "header.endianness");
    }
    {
        auto b = good;
        b.resize(b.size() - 1);
        expect(b, "truncated: header.file_size says");
        b = good;
        b.push_back(0);
        expect(b, "wrong size");
    }
    {
        auto b = good;
        b[good.size() - 3] ^= 0x10;  // inside the last block's values
        expect(b, "light 7: block CRC mismatch");
    }
    {
        auto b = good;
        b[kHeaderSize + 5] ^= 0x01;  // inside the metadata
        expect(b, "header CRC mismatch");
    }
    {
        // Past the CRCs: a coefficient index outside the grid, named with light and byte
        // (the plain layout, where indices sit at fixed offsets).
        const std::vector<std::uint8_t> plain =
            slurp(write_small(dir / "p.fgb", basis::Precision::Float16, basis::Entropy::None));
        auto b = plain;
        const auto index_offset = get<std::uint64_t>(plain, kOffIndexOffset);
        const auto off = get<std::uint64_t>(plain, std::size_t(index_offset));  // light 0's block
        // First index of direction 0 follows the block header and the 3 direction records.
        const std::size_t at = std::size_t(off + kBlockHeaderSize + 3 * kBlockDirRecordSize);
        put<std::uint16_t>(b, at, 60);  // the grid has 60 cells
        fix_crcs(b, plain);
        expect(b,
               ("byte " + std::to_string(at) + ", light 0): direction 0 coefficient 0: index 60 outside the 60 cells")
                   .c_str());
        // A duplicated index.
        b = plain;
        put<std::uint16_t>(b, at + 2, get<std::uint16_t>(plain, at));
        fix_crcs(b, plain);
        expect(b, "appears twice (first as coefficient 0)");
        // A lighting grid beyond the format's limit (4096 x 4096 x 8 = 2^27 cells).
        b = plain;
        const std::size_t dims_at = kHeaderSize + 4 + get<std::uint32_t>(plain, kHeaderSize);
        put<std::int32_t>(b, dims_at, 4096);
        put<std::int32_t>(b, dims_at + 4, 4096);
        put<std::int32_t>(b, dims_at + 8, 8);
        fix_crcs(b, plain);
        expect(b, "cells, the format allows 67108864");
    }
    // On disk (the ifstream path): truncated and empty files.
    auto b = good;
    b.resize(50);
    spit(dir / "t.fgb", b);
    CHECK_THROWS_WITH_AS(basis::load_fgb(dir / "t.fgb"), doctest::Contains("the fixed header alone is 104"),
                         core::Error);
    spit(dir / "e.fgb", {});
    CHECK_THROWS_AS(basis::load_fgb(dir / "e.fgb"), core::Error);
    CHECK_THROWS_WITH_AS(basis::load_fgb(dir / "missing.fgb"), doctest::Contains("cannot open"), core::Error);
}

namespace {

// Light 0's deflated block with its inflated stream changed by `mutate`, re-deflated and
// given a valid CRC (so only the stream's own checks can catch the damage). `size_delta`
// offsets the stored stream size; `trailing` bytes are appended after the zlib stream.
basis::EncodedBlock rebuilt_block(const basis::FgbMetadata& m,
                                  const std::function<void(std::vector<std::uint8_t>&)>& mutate,
                                  std::int64_t size_delta = 0, std::size_t trailing = 0) {
    const basis::EncodedBlock e = basis::encode_block(test::small_light(m, 0), m);
    const std::size_t head = basis::fgb::kBlockHeaderSize + m.bases() * basis::fgb::kBlockDirRecordSize;
    std::vector<std::uint8_t> raw(get<std::uint32_t>(e.bytes, head));
    uLongf n = raw.size();
    REQUIRE(uncompress(raw.data(), &n, e.bytes.data() + head + 4, uLong(e.bytes.size() - head - 4)) == Z_OK);
    REQUIRE(n == raw.size());
    mutate(raw);
    uLongf zn = compressBound(uLong(raw.size()));
    std::vector<std::uint8_t> z(zn);
    REQUIRE(compress2(z.data(), &zn, raw.data(), uLong(raw.size()), 6) == Z_OK);
    basis::EncodedBlock out;
    out.light = 0;
    out.bytes.assign(e.bytes.begin(), e.bytes.begin() + std::ptrdiff_t(head));
    const std::uint32_t size = std::uint32_t(std::int64_t(raw.size()) + size_delta);
    out.bytes.insert(out.bytes.end(), reinterpret_cast<const std::uint8_t*>(&size),
                     reinterpret_cast<const std::uint8_t*>(&size) + 4);
    out.bytes.insert(out.bytes.end(), z.begin(), z.begin() + std::ptrdiff_t(zn));
    out.bytes.insert(out.bytes.end(), trailing, std::uint8_t(0));
    out.crc = basis::crc32_of(out.bytes);
    return out;
}

std::vector<std::uint8_t> file_with(const std::filesystem::path& path, const basis::FgbMetadata& m,
                                    const basis::EncodedBlock& block0) {
    basis::FgbWriter w(path, m);
    w.add(block0);
    for (std::uint32_t l = 1; l < m.light_count(); ++l) w.add(test::small_light(m, l));
    w.finish();
    return slurp(path);
}

}  // namespace

TEST_CASE("deflated blocks: damage inside a stream with valid checksums is named, never misread") {
    const auto dir = test::scratch_dir("fgb_deflate");
    const basis::FgbMetadata m = small_meta(basis::Precision::Float16, basis::Entropy::Deflate);
    std::size_t total = 0;
    for (const auto& b : test::small_light(m, 0).directions) total += b.size();
    REQUIRE(total > 0);
    auto expect = [&](const basis::EncodedBlock& block, const char* needle) {
        CHECK_THROWS_WITH_AS(load_bytes(file_with(dir / "d.fgb", m, block)), doctest::Contains(needle), core::Error);
    };
    // Unchanged stream: accepted and identical to the light.
    CHECK(load_bytes(file_with(dir / "d.fgb", m, rebuilt_block(m, [](auto&) {}))).lights[0] == test::small_light(m, 0));
    // The first index gap (one byte: the grid has 60 cells) pointing past the grid.
    expect(rebuilt_block(m, [](auto& raw) { raw[0] = 60; }),
           "direction 0 coefficient 0: index 60 outside the 60 cells");
    // A gap of 5 LEB128 bytes (indices need at most 4).
    expect(rebuilt_block(m, [](auto& raw) { raw.insert(raw.begin(), 4, std::uint8_t(0x80)); }),
           "index gap longer than 4 bytes");
    // One byte more of gaps than the coefficients use.
    expect(rebuilt_block(m, [&](auto& raw) { raw.insert(raw.end() - std::ptrdiff_t(2 * total), std::uint8_t(0)); }),
           "1 bytes of index gaps left over");
    // A float16 value with an all-ones exponent (high-byte plane first).
    expect(rebuilt_block(m, [&](auto& raw) { raw[raw.size() - 2 * total] = 0x7e; }), "float16 value is not finite");
    // Stream sizes that lie: one byte more than inflates, or more than any deflate stream can give.
    expect(rebuilt_block(
               m, [](auto&) {}, +1),
           "the deflated coefficients are damaged");
    // (a non-minimal but valid 2-byte first gap keeps size - 1 above the size's lower bound)
    auto longer_gap = [](auto& raw) {
        raw[0] |= 0x80;
        raw.insert(raw.begin() + 1, std::uint8_t(0));
    };
    CHECK(load_bytes(file_with(dir / "d.fgb", m, rebuilt_block(m, longer_gap))).lights[0] == test::small_light(m, 0));
    expect(rebuilt_block(m, longer_gap, -1), "more data than the stream size");
    expect(rebuilt_block(
               m, [](auto&) {}, std::int64_t(1) << 31),
           "bytes cannot hold");
    // Bytes after the end of the zlib stream.
    expect(rebuilt_block(
               m, [](auto&) {}, 0, 3),
           "3 bytes unread");
}

TEST_CASE("every truncation and 6000 random byte corruptions are rejected without a crash") {
    const auto dir = test::scratch_dir("fgb_fuzz");
    for (const auto entropy : {basis::Entropy::Deflate, basis::Entropy::None})
        for (const auto prec : {basis::Precision::Float16, basis::Precision::Float32}) {
            const std::vector<std::uint8_t> good = slurp(write_small(dir / "f.fgb", prec, entropy));
            CHECK_NOTHROW(load_bytes(good));
            INFO("file of " << good.size() << " bytes, " << basis::to_string(prec) << ", "
                            << basis::to_string(entropy));
            std::size_t rejected = 0;
            for (std::size_t len = 0; len < good.size(); ++len) {
                try {
                    load_bytes(std::vector<std::uint8_t>(good.begin(), good.begin() + std::ptrdiff_t(len)));
                    FAIL_CHECK("truncation to " << len << " bytes was accepted");
                } catch (const core::Error& e) {
                    ++rejected;
                    CHECK(std::string(e.what()).find("mem.fgb") != std::string::npos);
                }
            }
            CHECK(rejected == good.size());
            // Random single-byte corruptions (any value but the original) anywhere in the file:
            // every byte is covered by a CRC, so each must be rejected.
            core::Rng rng(test::run_seed(), std::uint64_t(prec) + 2 * std::uint64_t(entropy));
            for (int t = 0; t < 1500; ++t) {
                auto b = good;
                const std::size_t at = rng.uniform_below(std::uint32_t(b.size()));
                b[at] ^= std::uint8_t(1 + rng.uniform_below(255));
                try {
                    load_bytes(std::move(b));
                    FAIL_CHECK("corruption of byte " << at << " was accepted");
                } catch (const core::Error&) {}
            }
        }
}

TEST_CASE("corruptions that get past the CRCs reach the structural checks and never crash") {
    // With the checksums recomputed, the parser's own bounds checks are all that stands
    // between a hostile file and the process: each load must either throw core::Error or
    // return data that satisfies every invariant the run time relies on.
    const auto dir = test::scratch_dir("fgb_fuzz2");
    for (const auto entropy : {basis::Entropy::None, basis::Entropy::Deflate}) {
        INFO(basis::to_string(entropy));
        const std::vector<std::uint8_t> good = slurp(write_small(dir / "f.fgb", basis::Precision::Float16, entropy));
        core::Rng rng(test::run_seed(), 3 + std::uint64_t(entropy));
        int rejected = 0, accepted = 0;
        for (int t = 0; t < 3000; ++t) {
            auto b = good;
            const int flips = 1 + int(rng.uniform_below(3));
            for (int f = 0; f < flips; ++f) {
                const std::size_t at = rng.uniform_below(std::uint32_t(b.size()));
                if (rng.uniform_below(4) == 0)
                    b[at] = std::uint8_t(rng.uniform_below(2) ? 0xff : 0x00);  // extreme values in sizes
                else
                    b[at] ^= std::uint8_t(1u << rng.uniform_below(8));
            }
            fix_crcs(b, good);
            try {
                const basis::BakedBasis bb = load_bytes(std::move(b));
                ++accepted;
                basis::validate(bb.meta, "accepted file");
                REQUIRE(bb.lights.size() == bb.meta.light_count());
                for (const auto& l : bb.lights) {
                    REQUIRE(l.directions.size() == bb.meta.bases());
                    for (const auto& d : l.directions) {
                        REQUIRE(d.index.size() == d.value.size());
                        for (std::size_t k = 0; k < d.size(); ++k) {
                            REQUIRE(d.index[k] < bb.meta.cells());
                            REQUIRE(std::isfinite(d.value[k]));
                        }
                        REQUIRE(std::isfinite(d.gamma));
                    }
                }
            } catch (const core::Error&) {
                ++rejected;
            }
        }
        MESSAGE("CRC-patched corruptions (" << basis::to_string(entropy) << "): " << rejected << " rejected, "
                                            << accepted << " accepted as valid data");
        // Most structural damage is caught; the rest changes only values (2240-2580 of 3000
        // rejected over random seeds: 1000 leaves room for any seed).
        CHECK(rejected > 1000);
    }
}

TEST_CASE("a consistent but wrong file: its header is checked against the plan, and values that overflow when lit") {
    const auto dir = test::scratch_dir("fgb_consistent");
    const basis::FgbMetadata m = small_meta(basis::Precision::Float16, basis::Entropy::Deflate);
    const auto path = write_small(dir / "m.fgb", basis::Precision::Float16);
    CHECK_NOTHROW(FgbReader(path).check_metadata(m));
    // The same key over other geometry (what a header edited with its checksums recomputed
    // says): each field is named.
    auto refused = [&](basis::FgbMetadata other, const char* field) {
        CAPTURE(field);
        const auto p = dir / "other.fgb";
        basis::FgbWriter w(p, other);
        for (std::uint32_t l = 0; l < other.light_count(); ++l) w.add(test::small_light(other, l));
        w.finish();
        CHECK_THROWS_WITH_AS(FgbReader(p).check_metadata(m), doctest::Contains(field), core::Error);
    };
    basis::FgbMetadata o = m;
    o.lighting.origin.x += 1.0;
    refused(o, "header.lighting.origin");
    o = m;
    o.lighting.voxel_size *= 2.0;
    refused(o, "header.lighting.voxel_size");
    o = m;
    o.lights.x[0] -= 1.0;
    refused(o, "metadata.lights");
    o = m;
    o.compression.xi = 0.5;
    refused(o, "metadata.compression");

    // scale_exp 112 is legal for the format but its values reach 2^128: refused at load, not
    // when a bolt lights the basis.
    basis::CompressedLight big = test::small_light(m, 0);
    basis::CompressedBasis& b = big.directions[0];
    REQUIRE(b.size() > 0);
    for (float& v : b.value) v = std::ldexp(v, 112 - b.scale_exp);
    b.scale_exp = 112;
    {
        basis::FgbWriter w(dir / "big.fgb", m);
        w.add(big);
        for (std::uint32_t l = 1; l < m.light_count(); ++l) w.add(test::small_light(m, l));
        w.finish();
    }
    CHECK_THROWS_WITH_AS(basis::load_fgb(dir / "big.fgb"), doctest::Contains("scale_exp: 112"), core::Error);
    CHECK_THROWS_WITH_AS(basis::load_fgb(dir / "big.fgb"), doctest::Contains("overflow float32 once lit"), core::Error);
    // Float32 values beyond 2^64 likewise.
    const basis::FgbMetadata m32 = small_meta(basis::Precision::Float32, basis::Entropy::None);
    basis::CompressedLight big32 = test::small_light(m32, 0);
    REQUIRE(big32.directions[0].size() > 0);
    big32.directions[0].value[0] = 1e30f;
    {
        basis::FgbWriter w(dir / "big32.fgb", m32);
        w.add(big32);
        for (std::uint32_t l = 1; l < m32.light_count(); ++l) w.add(test::small_light(m32, l));
        w.finish();
    }
    CHECK_THROWS_WITH_AS(basis::load_fgb(dir / "big32.fgb"), doctest::Contains("beyond 2^64"), core::Error);
}

TEST_CASE("a stale key names the first differing line; an edited description is told from a collision") {
    const basis::BakeKey scene = basis::BakeKey::from_description("a=1\nb=2\n");
    const basis::BakeKey other = basis::BakeKey::from_description("a=1\nb=3\n");
    CHECK(basis::key_difference(other, scene) ==
          "first difference at line 2: the file has \"b=3\", the scene has \"b=2\"");
    // The file's description edited after the bake, its hash left as the scene's: not a collision.
    basis::BakeKey edited = scene;
    edited.description = "a=1\nb=3\n";
    CHECK(basis::key_difference(edited, scene).find("it was edited after the bake") != std::string::npos);
    CHECK(basis::key_difference(edited, scene).find("collision") == std::string::npos);
}
