// Bounded reads and safe writes (core.h, "Files"): regular-file and size checks before reading,
// AtomicFile (temporary, checked write and close, atomic rename, lock, cleanup on exceptions,
// signals and file-size limits), outputs that alias inputs, and the finite-value check.
#include "core/core.h"
#include "support/test_support.h"

#include <doctest/doctest.h>

#include <poll.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <fstream>
#include <limits>

using namespace fulgur::core;
using fulgur::test::scratch_dir;

namespace {

// Files in `dir` other than `keep` (temporaries and lock files left behind).
std::vector<std::string> leftovers(const std::filesystem::path& dir, std::initializer_list<std::string> keep) {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        const std::string n = e.path().filename().string();
        if (std::find(keep.begin(), keep.end(), n) == keep.end()) out.push_back(n);
    }
    return out;
}

// Runs fn in a child process; returns its wait status.
template <class F>
int in_child(F&& fn) {
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        try {
            fn();
        } catch (...) {
            ::_exit(90);
        }
        ::_exit(0);
    }
    int status = 0;
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    return status;
}

Grid3<float> small_grid() {
    GridGeometry g;
    g.dims = {4, 3, 2};
    g.voxel_size = 10.0;
    Grid3<float> grid(g);
    for (std::size_t i = 0; i < grid.size(); ++i) grid.data[i] = float(i);
    return grid;
}

}  // namespace

TEST_CASE("reads: only regular files of bounded size") {
    const auto dir = scratch_dir("files_read");
    REQUIRE(::mkfifo((dir / "fifo").c_str(), 0600) == 0);
    CHECK_THROWS_WITH_AS(read_file(dir / "fifo", 100, "scene"), doctest::Contains("is a FIFO"), Error);
    CHECK_THROWS_WITH_AS(read_file(dir, 100, "scene"), doctest::Contains("is a directory"), Error);
    CHECK_THROWS_WITH_AS(read_file("/dev/zero", 100, "scene"), doctest::Contains("is a character device"), Error);
    CHECK_THROWS_WITH_AS(read_file(dir / "none", 100, "scene"), doctest::Contains("cannot open scene file"), Error);
    fulgur::test::write_text(dir / "f", std::string(101, 'x'));
    CHECK_THROWS_WITH_AS(read_file(dir / "f", 100, "scene"), doctest::Contains("the limit is 100 bytes"), Error);
    CHECK(read_file(dir / "f", 101, "scene") == std::string(101, 'x'));
}

TEST_CASE("NRRD reads: devices, FIFOs, huge lines and absurd spacings are refused before allocating") {
    const auto dir = scratch_dir("files_nrrd");
    write_nrrd(dir / "g.nrrd", small_grid());
    const std::string good = fulgur::test::read_text(dir / "g.nrrd");
    // cloud.file = /dev/zero once asked the allocator for 32 GB.
    CHECK_THROWS_WITH_AS(read_nrrd("/dev/zero"), doctest::Contains("is a character device"), Error);
    REQUIRE(::mkfifo((dir / "fifo.nrrd").c_str(), 0600) == 0);
    CHECK_THROWS_WITH_AS(read_nrrd(dir / "fifo.nrrd"), doctest::Contains("is a FIFO"), Error);
    // A 4 MB first line is not read whole: the header is bounded to 64 KiB.
    fulgur::test::write_text(dir / "line.nrrd", "NRRD0004\n" + std::string(4 << 20, 'x'));
    CHECK_THROWS_WITH_AS(read_nrrd(dir / "line.nrrd"), doctest::Contains("header longer than 64 KiB"), Error);
    // A spacing of 1e-300 m (once accepted, failing later as a "non-finite value") names the field.
    std::string s = good;
    const auto at = s.find("space directions: ");
    const auto eol = s.find('\n', at);
    s.replace(at, eol - at, "space directions: (1e-300,0,0) (0,1e-300,0) (0,0,1e-300)");
    fulgur::test::write_text(dir / "tiny.nrrd", s);
    CHECK_THROWS_WITH_AS(read_nrrd(dir / "tiny.nrrd"), doctest::Contains("voxel spacing must be in [1e-06, 1e+06]"),
                         Error);
    CHECK_THROWS_WITH_AS(read_nrrd(dir / "tiny.nrrd"), doctest::Contains("(byte "), Error);
    // The size limit is checked against the file before anything is read.
    CHECK_THROWS_WITH_AS(read_nrrd(dir / "g.nrrd", 64), doctest::Contains("the limit is 64 bytes"), Error);
    // The header alone sizes a load.
    const NrrdHeader h = read_nrrd_header(dir / "g.nrrd");
    CHECK(h.geom.dims == Int3{4, 3, 2});
    CHECK(h.file_size == good.size());
}

TEST_CASE("non-finite values never reach a file") {
    const auto dir = scratch_dir("files_finite");
    Grid3<float> g = small_grid();
    g.data[7] = std::numeric_limits<float>::infinity();
    CHECK_THROWS_WITH_AS(write_nrrd(dir / "inf.nrrd", g), doctest::Contains("voxel (3,1,0) is infinite"), Error);
    g.data[7] = std::numeric_limits<float>::quiet_NaN();
    CHECK_THROWS_WITH_AS(write_nrrd(dir / "nan.nrrd", g), doctest::Contains("is NaN"), Error);
    CHECK(leftovers(dir, {}).empty());  // no file, no temporary
    const float v[3] = {1.0f, -std::numeric_limits<float>::infinity(), 0.0f};
    CHECK_THROWS_WITH_AS(check_finite(v, "x.fgb: light 3", "coefficient"),
                         doctest::Contains("x.fgb: light 3: coefficient 1 is infinite"), Error);
}

TEST_CASE("AtomicFile: the target changes only on commit, and nothing is left behind") {
    const auto dir = scratch_dir("files_atomic");
    const auto out = dir / "out.bin";
    fulgur::test::write_text(out, "old");
    {
        AtomicFile f(out);
        f.write("new contents");
        CHECK(fulgur::test::read_text(out) == "old");  // the temporary is beside it
        CHECK(f.temp_path().parent_path() == out.parent_path());
        CHECK(std::filesystem::exists(f.temp_path()));
    }  // destroyed without commit (an exception): the old file stays, the temporary goes
    CHECK(fulgur::test::read_text(out) == "old");
    CHECK(leftovers(dir, {"out.bin"}).empty());
    write_file(out, "new");
    CHECK(fulgur::test::read_text(out) == "new");
    CHECK(leftovers(dir, {"out.bin"}).empty());
    // A temporary a killed writer left ("<name>.<pid>.tmp") is removed by the next writer.
    fulgur::test::write_text(dir / "out.bin.12345.tmp", "stale");
    write_file(out, "again");
    CHECK(leftovers(dir, {"out.bin"}).empty());
}

TEST_CASE("AtomicFile refuses devices and directories: /dev/full cannot report success") {
    CHECK_THROWS_WITH_AS(write_file("/dev/full", "x"), doctest::Contains("not a regular file"), Error);
    const auto dir = scratch_dir("files_dir_target");
    CHECK_THROWS_WITH_AS(write_file(dir, "x"), doctest::Contains("is a directory"), Error);
    // A PNG through the same path.
    const std::uint8_t px[4] = {1, 2, 3, 255};
    CHECK_THROWS_AS(write_png("/dev/full", 1, 1, 4, px), Error);
}

TEST_CASE("AtomicFile: a write past the file-size limit fails with an error and leaves no temporary") {
    const auto dir = scratch_dir("files_fsize");
    const auto out = dir / "big.bin";
    const int status = in_child([&] {
        struct rlimit rl {
            4096, 4096
        };
        ::setrlimit(RLIMIT_FSIZE, &rl);
        try {
            AtomicFile f(out);
            const std::string block(1 << 16, 'x');
            f.write(block);
            f.commit();
        } catch (const Error& e) {
            // The error names the target, and the temporary is already gone.
            const bool named = std::string(e.what()).find("big.bin") != std::string::npos;
            ::_exit(named ? 3 : 4);
        }
        ::_exit(5);
    });
    REQUIRE(WIFEXITED(status));
    CHECK(WEXITSTATUS(status) == 3);
    CHECK(leftovers(dir, {}).empty());
}

TEST_CASE("AtomicFile: a terminating signal removes the temporary and the lock and still stops the process") {
    const int signals[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGPIPE, SIGXCPU, SIGVTALRM};
    for (int sig : signals) {
        CAPTURE(sig);
        const auto dir = scratch_dir("files_signal");
        const auto out = dir / "s.bin";
        fulgur::test::write_text(out, "previous");
        const int status = in_child([&] {
            for (int s : signals) ::signal(s, SIG_DFL);  // as in a tool (no test framework handler)
            // SIGQUIT and SIGXCPU dump core by default: none from this test.
            const struct rlimit no_core { 0, 0 };
            ::setrlimit(RLIMIT_CORE, &no_core);
            AtomicFile f(out);
            f.write("partial");
            ::raise(sig);
            ::_exit(7);  // not reached: the signal's default action follows the cleanup
        });
        CHECK(WIFSIGNALED(status));
        if (WIFSIGNALED(status)) CHECK(WTERMSIG(status) == sig);
        CHECK(fulgur::test::read_text(out) == "previous");
        CHECK(leftovers(dir, {"s.bin"}).empty());  // neither the temporary nor the lock file
    }
}

TEST_CASE("FileLock: a second writer of one path waits for the first; the result is one whole file") {
    const auto dir = scratch_dir("files_lock");
    const auto out = dir / "shared.bin";
    int go[2], done[2];
    REQUIRE(::pipe(go) == 0);
    REQUIRE(::pipe(done) == 0);
    // The child is made before the parent locks: a child forked while the lock is held would
    // share the lock's open file and keep it locked after the parent lets go.
    const pid_t pid = ::fork();
    REQUIRE(pid >= 0);
    if (pid == 0) {
        char c = 0;
        if (::read(go[0], &c, 1) != 1) ::_exit(92);
        try {
            AtomicFile f(out);  // waits for the parent's lock
            f.write(std::string(100000, 'b'));
            f.commit();
        } catch (...) {
            ::_exit(91);
        }
        (void)!::write(done[1], &c, 1);
        ::_exit(0);
    }
    auto lock = std::make_unique<FileLock>(out);
    const char c = 'x';
    REQUIRE(::write(go[1], &c, 1) == 1);
    // While the lock is held the child cannot finish (order, not time, is checked: the poll
    // only gives it the chance to run).
    struct pollfd p {
        done[0], POLLIN, 0
    };
    CHECK(::poll(&p, 1, 300) == 0);
    write_file(out, std::string(50000, 'a'));  // nested in this process: no wait
    lock.reset();
    int status = 0;
    REQUIRE(::waitpid(pid, &status, 0) == pid);
    CHECK((WIFEXITED(status) && WEXITSTATUS(status) == 0));
    for (int fd : {go[0], go[1], done[0], done[1]}) ::close(fd);
    const std::string got = fulgur::test::read_text(out);
    CHECK(got.size() == 100000);
    CHECK(got.find_first_not_of('b') == std::string::npos);
    CHECK(leftovers(dir, {"shared.bin"}).empty());
}

TEST_CASE("outputs never alias an input or each other: paths, dot segments, symbolic and hard links") {
    const auto dir = scratch_dir("files_alias");
    fulgur::test::write_text(dir / "s.json", "{}");
    const NamedPath scene{"scene", dir / "s.json"};
    auto refuses = [&](const std::filesystem::path& out) {
        const NamedPath o{"output", out};
        CHECK_THROWS_WITH_AS(check_distinct_files(std::span(&scene, 1), std::span(&o, 1)),
                             doctest::Contains("would overwrite the scene"), Error);
    };
    refuses(dir / "s.json");
    refuses(dir / "sub" / ".." / "s.json");
    std::filesystem::create_symlink(dir / "s.json", dir / "link.json");
    refuses(dir / "link.json");
    std::filesystem::create_hard_link(dir / "s.json", dir / "hard.json");
    refuses(dir / "hard.json");
    const NamedPath two[2] = {{"image", dir / "a.png"}, {"reference", dir / "." / "a.png"}};
    CHECK_THROWS_WITH_AS(check_distinct_files(std::span(&scene, 1), two), doctest::Contains("are the same file"),
                         Error);
    // Relative paths none of whose parts exist (weakly_canonical alone leaves them unchanged).
    const NamedPath rel[2] = {{"baked file", "no_such_out.fgb"}, {"report", "./no_such_dir/../no_such_out.fgb"}};
    CHECK_THROWS_WITH_AS(check_distinct_files({}, rel), doctest::Contains("are the same file"), Error);
    const NamedPath fine[2] = {{"image", dir / "a.png"}, {"reference", dir / "b.png"}};
    CHECK_NOTHROW(check_distinct_files(std::span(&scene, 1), fine));
}
