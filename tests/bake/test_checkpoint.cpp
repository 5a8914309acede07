// The bake's checkpoint (bake/detail/checkpoint.h): a bake stopped after some chunks resumes
// to the same bytes and the same figures; a corrupt, foreign or tampered checkpoint is
// refused with a message naming the file, and never used; the results' serialization.
// Scenes: the tiny golden-test scenes (32x32x16 density, 8x8x4 lighting grid).
#include "bake/bake.h"
#include "bake/detail/checkpoint.h"
#include "support/stop_hook.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <zlib.h>

#include <algorithm>
#include <fstream>
#include <iterator>

using namespace fulgur;
namespace fs = std::filesystem;

namespace {

scene::Scene tiny(const std::string& name) {
    return scene::load_scene(test::source_dir() / "tests/apps/scenes" / (name + ".json"));
}

std::vector<std::uint8_t> read_bytes(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), {}};
}

void write_bytes(const fs::path& p, const std::vector<std::uint8_t>& b) {
    std::ofstream(p, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
}

bake::Plan plan_of(const scene::Scene& s, const core::Grid3<float>& d, int threads) {
    bake::PlanOptions o;
    o.estimate = false;
    o.threads = threads;
    bake::Plan p = bake::make_plan(s, d, o);
    p.threads = threads;
    return p;
}

// Bakes with a checkpoint and stops it once `after` lights are kept; returns the lights kept.
std::size_t bake_until(const scene::Scene& s, const core::Grid3<float>& d, const bake::Plan& plan, const fs::path& out,
                       std::size_t after) {
    std::size_t kept = 0;
    const bake::BakeOptions o = test::stop_after(out, after, kept);
    CHECK_THROWS_AS(bake::bake(s, d, plan, out, o), test::Stop);
    return kept;
}

std::string refusal(const scene::Scene& s, const core::Grid3<float>& d, const bake::Plan& plan, const fs::path& out) {
    bake::BakeOptions o;
    o.checkpoint = bake::checkpoint_path(out);
    try {
        bake::bake(s, d, plan, out, o);
    } catch (const core::Error& e) {
        return e.what();
    }
    return "(accepted)";
}

fs::path first_chunk(const fs::path& dir, const std::string& ext) {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().extension() == ext) files.push_back(e.path());
    REQUIRE_FALSE(files.empty());
    std::sort(files.begin(), files.end());
    return files.front();
}

}  // namespace

TEST_CASE("checkpoint: a stopped bake resumes to the same bytes and figures, then the checkpoint is gone") {
    const scene::Scene s = tiny("test_aniso_ms_cg");
    const core::Grid3<float> d = scene::make_density(s);
    const fs::path dir = test::scratch_dir("checkpoint_resume");
    const bake::Plan plan = plan_of(s, d, 2);
    const std::size_t n = plan.lights.count();
    REQUIRE(n >= 8);
    const bake::Report whole = bake::bake(s, d, plan, dir / "whole.fgb");

    const fs::path out = dir / "resumed.fgb";
    const std::size_t kept = bake_until(s, d, plan, out, 4);
    CHECK(kept >= 4);
    CHECK(kept < n);
    CHECK_FALSE(fs::exists(out));  // a stopped bake writes no file
    CHECK(fs::is_directory(bake::checkpoint_path(out)));

    std::size_t calls = 0, last = 0;
    bake::BakeOptions o;
    o.checkpoint = bake::checkpoint_path(out);
    const bake::Report r = bake::bake(s, d, plan, out, o, [&](std::size_t done, std::size_t total, double) {
        ++calls;
        CHECK(total == n - kept);  // progress counts this run's lights
        last = done;
    });
    CHECK(r.lights_resumed == kept);
    CHECK(last == n - kept);
    CHECK(read_bytes(out) == read_bytes(dir / "whole.fgb"));
    CHECK_FALSE(fs::exists(bake::checkpoint_path(out)));
    CHECK(test::temporaries(dir).empty());
    // The resumed lights' figures came from the checkpoint: the report is the whole bake's.
    CHECK(r.lights == whole.lights);
    CHECK(r.lights_dropped == whole.lights_dropped);
    CHECK(r.coefficients_kept == whole.coefficients_kept);
    CHECK(r.max_solver_iterations == whole.max_solver_iterations);
    CHECK(r.unconverged == whole.unconverged);
    // The same per-light squared norms summed in another order: double rounding only.
    CHECK(r.relative_l2_error == doctest::Approx(whole.relative_l2_error).epsilon(1e-9));
    CHECK(r.mean_solver_iterations == doctest::Approx(whole.mean_solver_iterations).epsilon(1e-12));
}

TEST_CASE("checkpoint: corrupt, truncated, foreign or stray files are refused with the file named, never used") {
    const scene::Scene s = tiny("test_iso_ss_ic");
    const core::Grid3<float> d = scene::make_density(s);
    const fs::path dir = test::scratch_dir("checkpoint_refused");
    const bake::Plan plan = plan_of(s, d, 1);
    const fs::path out = dir / "s.fgb", ck = bake::checkpoint_path(out);
    auto fresh_checkpoint = [&] {
        fs::remove_all(ck);
        bake_until(s, d, plan, out, 4);
    };
    auto refused = [&](const std::string& file, const std::string& why) {
        const std::string m = refusal(s, d, plan, out);
        INFO(m);
        CHECK(m.find(file) != std::string::npos);
        CHECK(m.find(why) != std::string::npos);
        CHECK(m.find("not used") != std::string::npos);
        CHECK_FALSE(fs::exists(out));
        CHECK(fs::is_directory(ck));  // left for the user to inspect or remove
    };

    SUBCASE("a flipped byte in a chunk's blocks") {
        fresh_checkpoint();
        const fs::path f = first_chunk(ck, ".fgb");
        std::vector<std::uint8_t> b = read_bytes(f);
        b[b.size() - 3] ^= 0x10;  // inside the last block
        write_bytes(f, b);
        refused(f.filename().string(), "CRC");
    }
    SUBCASE("a truncated chunk") {
        fresh_checkpoint();
        const fs::path f = first_chunk(ck, ".fgb");
        fs::resize_file(f, fs::file_size(f) - 5);
        refused(f.filename().string(), "truncated");
    }
    SUBCASE("a flipped byte in a chunk's figures") {
        fresh_checkpoint();
        const fs::path f = first_chunk(ck, ".stats");
        std::vector<std::uint8_t> b = read_bytes(f);
        b[40] ^= 0x01;
        write_bytes(f, b);
        refused(f.filename().string(), "CRC-32 mismatch");
    }
    SUBCASE("figures without their blocks' file are a killed writer's: removed, the chunk solved again") {
        fresh_checkpoint();
        fs::remove(first_chunk(ck, ".fgb"));
        bake::BakeOptions o;
        o.checkpoint = ck;
        const bake::Report r = bake::bake(s, d, plan, out, o);
        CHECK(r.lights_resumed == 2);  // 2 chunks of 2 were kept, one lost its blocks
        bake::bake(s, d, plan, dir / "whole.fgb");
        CHECK(read_bytes(out) == read_bytes(dir / "whole.fgb"));
        fs::remove(out);
    }
    SUBCASE("another scene's checkpoint") {
        scene::Scene t = s;
        t.medium.albedo = 0.5;
        const bake::Plan other = plan_of(t, d, 1);
        fs::remove_all(ck);
        const fs::path t_out = dir / "t.fgb";
        fs::remove_all(bake::checkpoint_path(t_out));
        bake_until(t, d, other, t_out, 2);
        fs::rename(bake::checkpoint_path(t_out), ck);
        refused(".fgb", "medium.albedo");  // the stale key names the changed parameter
    }
    SUBCASE("another scene's figures beside this scene's blocks") {
        fresh_checkpoint();
        scene::Scene t = s;
        t.medium.albedo = 0.5;
        const bake::Plan other = plan_of(t, d, 1);
        const fs::path t_out = dir / "t.fgb";
        fs::remove_all(bake::checkpoint_path(t_out));
        bake_until(t, d, other, t_out, 2);
        const fs::path f = first_chunk(ck, ".stats");
        fs::copy_file(bake::checkpoint_path(t_out) / f.filename(), f, fs::copy_options::overwrite_existing);
        refused(f.filename().string(), "a checkpoint of another scene or settings");
    }
    SUBCASE("a checkpoint holding every light: nothing left to solve, the same file") {
        fs::remove_all(ck);
        const std::size_t n = plan.lights.count();
        bake_until(s, d, plan, out, n);
        bake::BakeOptions o;
        o.checkpoint = ck;
        const bake::Report r = bake::bake(s, d, plan, out, o);
        CHECK(r.lights_resumed == n);
        bake::bake(s, d, plan, dir / "whole.fgb");
        CHECK(read_bytes(out) == read_bytes(dir / "whole.fgb"));
        CHECK_FALSE(fs::exists(ck));
        fs::remove(out);
    }
    SUBCASE("a stray file") {
        fresh_checkpoint();
        test::write_text(ck / "notes.txt", "mine");
        refused("notes.txt", "not a file of a bake's checkpoint");
    }
    SUBCASE("a chunk outside the plan's lights") {
        fresh_checkpoint();
        const fs::path f = first_chunk(ck, ".fgb");
        const std::uint32_t n = std::uint32_t(plan.lights.count());
        const std::string name = bake::detail::Checkpoint::stem({n, n + 2});
        fs::rename(f, ck / (name + ".fgb"));
        refused(name, "not a range of this bake's");
    }
}

TEST_CASE("results: serialized and read back exactly; damaged messages are refused naming the byte") {
    std::vector<bake::LightResult> r(3);
    for (std::uint32_t i = 0; i < 3; ++i) {
        r[i].block.light = 7 + i;
        r[i].block.bytes = {std::uint8_t(i), 2, 3, std::uint8_t(40 + i)};
        r[i].seconds_single = 0.25 * i;
        r[i].ref2 = 1.5 + i;
        r[i].err2 = 1e-9 * i;
        r[i].coefficients = 100 + i;
        r[i].iterations = i == 1 ? -1 : 30;
        r[i].converged = i != 2;
        r[i].dropped_fraction = i == 1 ? 1e-7 : -1.0;
    }
    for (bake::LightResult& x : r)  // the CRC-32 the .fgb stores with a block
        x.block.crc = std::uint32_t(::crc32(::crc32(0L, Z_NULL, 0), x.block.bytes.data(), uInt(x.block.bytes.size())));
    const std::vector<std::uint8_t> figures = bake::encode_results(r, false);
    const std::vector<bake::LightResult> back = bake::decode_results(figures, false, 7, 10, "figures");
    REQUIRE(back.size() == 3);
    for (std::size_t i = 0; i < 3; ++i) {
        CHECK(back[i].block.light == r[i].block.light);
        CHECK(back[i].ref2 == r[i].ref2);
        CHECK(back[i].err2 == r[i].err2);
        CHECK(back[i].coefficients == r[i].coefficients);
        CHECK(back[i].iterations == r[i].iterations);
        CHECK(back[i].converged == r[i].converged);
        CHECK(back[i].dropped_fraction == r[i].dropped_fraction);
        CHECK(back[i].block.bytes.empty());
    }
    CHECK_THROWS_WITH_AS(bake::decode_results(figures, false, 8, 11, "figures"), doctest::Contains("expected light 8"),
                         core::Error);
    const std::vector<std::uint8_t> cut(figures.begin(), figures.end() - 1);
    CHECK_THROWS_WITH_AS(bake::decode_results(cut, false, 7, 10, "figures"), doctest::Contains("truncated"),
                         core::Error);
    // With blocks: the bytes come back, and each block's CRC-32 is checked.
    std::vector<std::uint8_t> message = bake::encode_results(r, true);
    const std::vector<bake::LightResult> whole = bake::decode_results(message, true, 7, 10, "message");
    for (std::size_t i = 0; i < 3; ++i) CHECK(whole[i].block.bytes == r[i].block.bytes);
    message.back() ^= 0x01;
    CHECK_THROWS_WITH_AS(bake::decode_results(message, true, 7, 10, "message"), doctest::Contains("CRC-32"),
                         core::Error);
}
