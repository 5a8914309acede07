// The bake over the ranks of a Session (distributed.h): rank 0 runs bake::bake with the other
// ranks as its Helpers; the others ask for chunks, solve them and send back their blocks.
//
// Protocol (detail/mpi.h tags): every helper starts by sending an empty result (a request);
// rank 0 answers each result with the next chunk, or with an empty chunk when none is left,
// which releases the helper. A helper's failure is sent to rank 0 as text and ends the bake
// there. Rank 0 serves from the thread that called bake() (MPI_THREAD_FUNNELED), polling,
// while its worker threads solve chunks too.
#include "distributed/distributed.h"

#ifdef FULGUR_HAVE_MPI
#include "distributed/detail/mpi.h"
#endif

#include <cinttypes>
#include <cstdio>
#include <cstring>

namespace fulgur::distributed {

#ifdef FULGUR_HAVE_MPI

namespace {

using detail::check;

std::vector<std::uint8_t> chunk_header(bake::Chunk c) {
    std::vector<std::uint8_t> b(8);
    std::memcpy(b.data(), &c.begin, 4);
    std::memcpy(b.data() + 4, &c.end, 4);
    return b;
}

bake::Chunk read_chunk(std::span<const std::uint8_t> b, const std::string& where) {
    if (b.size() < 8)
        throw core::Error(where, "a message of " + std::to_string(b.size()) + " bytes, at least 8 expected");
    bake::Chunk c;
    std::memcpy(&c.begin, b.data(), 4);
    std::memcpy(&c.end, b.data() + 4, 4);
    if (c.end < c.begin)
        throw core::Error(where, "chunk " + std::to_string(c.begin) + ".." + std::to_string(c.end) + " is reversed");
    return c;
}

// Rank 0's view of the other ranks.
class MpiHelpers final : public bake::Helpers {
public:
    MpiHelpers(int ranks, int helper_threads, std::uint32_t lights)
        : ranks_(ranks), threads_(helper_threads), lights_(lights), working_(std::size_t(ranks), bake::Chunk{}) {}

    int threads() const override { return threads_; }

    bool poll(const std::function<std::optional<bake::Chunk>()>& next,
              const std::function<void(bake::Chunk, std::vector<bake::LightResult>&&)>& deliver, bool& busy) override {
        for (;;) {
            int flag = 0;
            MPI_Status st;
            check(MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st), "MPI_Iprobe");
            if (!flag) break;
            busy = true;
            const int from = st.MPI_SOURCE;
            const std::string who = "rank " + std::to_string(from);
            const std::vector<std::uint8_t> msg = detail::receive_bytes(st);
            if (st.MPI_TAG == detail::kTagError) throw core::Error(who, std::string(msg.begin(), msg.end()));
            if (st.MPI_TAG != detail::kTagResult)
                throw core::Error(who, "unexpected message tag " + std::to_string(st.MPI_TAG));
            const bake::Chunk c = read_chunk(msg, who);
            const bake::Chunk expected = working_[std::size_t(from)];
            if (c.begin != expected.begin || c.end != expected.end)
                throw core::Error(who, "sent lights " + std::to_string(c.begin) + ".." + std::to_string(c.end) +
                                           ", it was given " + std::to_string(expected.begin) + ".." +
                                           std::to_string(expected.end));
            if (c.size())
                deliver(c, bake::decode_results(std::span(msg).subspan(8), true, c.begin, c.end,
                                                who + "'s results for lights " + std::to_string(c.begin) + ".." +
                                                    std::to_string(c.end)));
            const std::optional<bake::Chunk> work = next();
            working_[std::size_t(from)] = work ? *work : bake::Chunk{lights_, lights_};
            detail::send_bytes(chunk_header(working_[std::size_t(from)]), from, detail::kTagWork);
            if (!work) ++released_;
        }
        return released_ == ranks_ - 1;
    }

private:
    int ranks_, threads_;
    std::uint32_t lights_;
    std::vector<bake::Chunk> working_;  // per rank: the chunk it was given last
    int released_ = 0;
};

// A helper rank: requests, solves and returns chunks until rank 0 releases it.
void help(const scene::Scene& s, const core::Grid3<float>& density, const bake::Plan& plan) {
    const solve::Media media = solve::make_media(s, density);
    std::vector<std::uint8_t> result = chunk_header({});
    for (;;) {
        detail::send_bytes(result, 0, detail::kTagResult);
        const std::vector<std::uint8_t> msg = detail::receive_bytes(detail::wait_for(0, detail::kTagWork));
        const bake::Chunk c = read_chunk(msg, "rank 0");
        if (c.size() == 0) return;
        try {
            const std::vector<bake::LightResult> r = bake::bake_lights(s, media, plan, c.begin, c.end);
            result = chunk_header(c);
            const std::vector<std::uint8_t> body = bake::encode_results(r, true);
            result.insert(result.end(), body.begin(), body.end());
        } catch (const std::exception& e) {
            const std::string text =
                std::string("lights ") + std::to_string(c.begin) + ".." + std::to_string(c.end) + ": " + e.what();
            detail::send_bytes(std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()), 0,
                               detail::kTagError);
            throw;
        }
    }
}

}  // namespace

std::optional<bake::Report> bake(const Session& session, const scene::Scene& s, const core::Grid3<float>& density,
                                 const bake::Plan& plan, const std::filesystem::path& out,
                                 const bake::BakeOptions& options, const bake::Progress& progress) {
    if (!session.distributed()) return bake::bake(s, density, plan, out, options, progress);
    // Every rank must bake the same plan: its scene key and thread count go to rank 0.
    const std::uint64_t mine[2] = {plan.metadata.key.hash, std::uint64_t(plan.threads)};
    std::vector<std::uint64_t> all(session.rank() == 0 ? 2 * std::size_t(session.size()) : 0);
    check(MPI_Gather(mine, 2, MPI_UINT64_T, all.data(), 2, MPI_UINT64_T, 0, MPI_COMM_WORLD), "MPI_Gather");
    if (session.rank() != 0) {
        help(s, density, plan);
        return std::nullopt;
    }
    int threads = 0;
    for (int r = 1; r < session.size(); ++r) {
        if (all[2 * std::size_t(r)] != plan.metadata.key.hash) {
            char msg[200];
            std::snprintf(msg, sizeof msg,
                          "its scene key is 0x%016" PRIx64 ", rank 0's 0x%016" PRIx64
                          ": every rank must read the same scene and cloud files",
                          all[2 * std::size_t(r)], plan.metadata.key.hash);
            throw core::Error("rank " + std::to_string(r), msg);
        }
        threads += int(all[2 * std::size_t(r) + 1]);
    }
    MpiHelpers helpers(session.size(), threads, std::uint32_t(plan.lights.count()));
    bake::BakeOptions o = options;
    o.helpers = &helpers;
    return bake::bake(s, density, plan, out, o, progress);
}

#else

std::optional<bake::Report> bake(const Session&, const scene::Scene& s, const core::Grid3<float>& density,
                                 const bake::Plan& plan, const std::filesystem::path& out,
                                 const bake::BakeOptions& options, const bake::Progress& progress) {
    return bake::bake(s, density, plan, out, options, progress);
}

#endif

}  // namespace fulgur::distributed
