// ik5r bulk harness: a Verilator C++ main that streams a file of packed input payloads through a
// generated stream block and writes every accepted output payload to a file (src/ik5r/tools/
// testbench/harness.py builds and runs it, and compares the outputs with the model in numpy).
//
// Files are raw little-endian 32-bit words, IK5R_IN_WORDS (IK5R_OUT_WORDS) per item. The clock
// is driven here, so a cycle costs one evaluation of the design and no VPI call. Valid and ready
// follow a full-rate or a random pattern (idles, back-pressure, long stalls) from a seeded
// xorshift generator. Checked on every cycle: an output that is offered and not taken keeps
// its payload and its valid (a hold violation), and nothing comes out beyond what went in.
//
// Usage: harness IN OUT COUNT SEED VALID_PERMILLE READY_PERMILLE STALLS CYCLE_LIMIT DRAIN
// (CYCLE_LIMIT: the run stops there with the outputs it has; Python sizes it from the block's
// cycles per result, so that only a hung block reaches it. DRAIN: cycles run after the last
// output with ready high, any output then an extra one; Python sizes it from the latency).
// Prints one line: "cycles C in I out O hold_violations H extra_outputs E".
// ik5r_ports.h (generated next to the block's Verilog) names its ports and payload word counts.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "Vdut.h"
#include "ik5r_ports.h"
#include "verilated.h"

namespace {

// Port accessors by Verilator's port types: CData/SData/IData (<= 32 bits), QData (<= 64 bits)
// and VlWide<N> (wider). Payload words above the port's width are zero (Python packs them so).
void put(CData& port, const uint32_t* w) { port = static_cast<CData>(w[0]); }
void put(SData& port, const uint32_t* w) { port = static_cast<SData>(w[0]); }
void put(IData& port, const uint32_t* w) { port = w[0]; }
void put(QData& port, const uint32_t* w) { port = static_cast<QData>(w[0]) | (static_cast<QData>(w[1]) << 32); }
template <std::size_t N>
void put(VlWide<N>& port, const uint32_t* w) {
    for (std::size_t k = 0; k < N; ++k) port[k] = w[k];
}

void get(const CData& port, uint32_t* w) { w[0] = port; }
void get(const SData& port, uint32_t* w) { w[0] = port; }
void get(const IData& port, uint32_t* w) { w[0] = port; }
void get(const QData& port, uint32_t* w) {
    w[0] = static_cast<uint32_t>(port);
    w[1] = static_cast<uint32_t>(port >> 32);
}
template <std::size_t N>
void get(const VlWide<N>& port, uint32_t* w) {
    for (std::size_t k = 0; k < N; ++k) w[k] = port[k];
}

// xorshift64*: the valid / ready patterns (reproducible from the seed, cheap per cycle).
struct Rng {
    uint64_t s;
    explicit Rng(uint64_t seed) : s(seed * 0x9E3779B97F4A7C15ULL + 1) {}
    uint32_t next() {
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        return static_cast<uint32_t>((s * 0x2545F4914F6CDD1DULL) >> 32);
    }
};

// One side's pattern: high with probability permille / 1000, and with ``stalls`` a stall of
// 50-199 low cycles starting with probability 1 / 2000 per cycle.
struct Pattern {
    Rng rng;
    uint32_t permille;
    bool stalls;
    uint32_t stall = 0;
    Pattern(uint64_t seed, uint32_t p, bool s) : rng(seed), permille(p), stalls(s) {}
    bool next() {
        if (permille >= 1000 && !stalls) return true;
        if (stall) { --stall; return false; }
        if (stalls && rng.next() % 2000 == 0) { stall = 50 + rng.next() % 150; return false; }
        return rng.next() % 1000 < permille;
    }
};

constexpr std::size_t kIn = IK5R_IN_WORDS;
constexpr std::size_t kOut = IK5R_OUT_WORDS;

// The block, its stimulus and what came out; one call of cycle() is one clock.
struct Harness {
    VerilatedContext ctx;
    Vdut dut{&ctx};
    const std::vector<uint32_t>& in;
    std::vector<uint32_t> out;
    uint64_t count, cycles = 0, sent = 0, got = 0, hold_violations = 0, extra = 0;
    bool valid_in = false, offered = false;     // offered: the output offered, not taken last cycle
    std::vector<uint32_t> held = std::vector<uint32_t>(kOut), now = std::vector<uint32_t>(kOut);

    Harness(const std::vector<uint32_t>& words, uint64_t n) : in(words), out(n * kOut), count(n) {}

    void reset() {
        dut.IK5R_CLK = 0;
        dut.IK5R_RST = 1;
        dut.IK5R_I_VALID = 0;
        dut.IK5R_O_READY = 0;
        for (int c = 0; c < 4; ++c) {
            dut.IK5R_CLK = 0; dut.eval();
            dut.IK5R_CLK = 1; dut.eval();
        }
        dut.IK5R_RST = 0;
    }

    // An output beat: stored if taken, checked against the one offered last cycle.
    void sample_output() {
        if (!dut.IK5R_O_VALID) {
            if (offered) ++hold_violations;     // valid dropped without a transfer
            offered = false;
            return;
        }
        get(dut.IK5R_O_PAYLOAD, now.data());
        if (offered && now != held) ++hold_violations;
        offered = !dut.IK5R_O_READY;
        if (offered) { held = now; return; }
        if (got < count) std::copy(now.begin(), now.end(), &out[got * kOut]);
        else ++extra;
        ++got;
    }

    // One clock: drive after the falling edge, sample the handshakes before the rising one.
    void cycle(bool offer, bool ready) {
        if (!valid_in && sent < count && offer) {
            put(dut.IK5R_I_PAYLOAD, &in[sent * kIn]);
            valid_in = true;
        }
        dut.IK5R_I_VALID = valid_in;
        dut.IK5R_O_READY = ready;
        dut.IK5R_CLK = 0;
        dut.eval();
        sample_output();
        if (valid_in && dut.IK5R_I_READY) { valid_in = false; ++sent; }
        dut.IK5R_CLK = 1;
        dut.eval();
        ++cycles;
    }
};

bool read_words(const char* path, std::vector<uint32_t>& words) {
    FILE* f = std::fopen(path, "rb");
    const bool ok = f && std::fread(words.data(), sizeof(uint32_t), words.size(), f) == words.size();
    if (f) std::fclose(f);
    return ok;
}

bool write_words(const char* path, const uint32_t* words, std::size_t n) {
    FILE* f = std::fopen(path, "wb");
    const bool ok = f && std::fwrite(words, sizeof(uint32_t), n, f) == n;
    return f && std::fclose(f) == 0 && ok;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 10) {
        std::fprintf(stderr, "usage: %s IN OUT COUNT SEED VALID_PERMILLE READY_PERMILLE STALLS CYCLE_LIMIT DRAIN\n",
                     argv[0]);
        return 2;
    }
    const uint64_t count = std::strtoull(argv[3], nullptr, 10);
    const uint64_t seed = std::strtoull(argv[4], nullptr, 10);
    Pattern vpat(seed, static_cast<uint32_t>(std::atoi(argv[5])), false);
    Pattern rpat(seed + 1, static_cast<uint32_t>(std::atoi(argv[6])), std::atoi(argv[7]) != 0);
    std::vector<uint32_t> in(count * kIn);
    if (!read_words(argv[1], in)) {
        std::fprintf(stderr, "harness: cannot read %llu items from %s\n", (unsigned long long)count, argv[1]);
        return 2;
    }
    Harness h(in, count);
    h.reset();
    const uint64_t limit = std::strtoull(argv[8], nullptr, 10);
    const uint64_t drain = std::strtoull(argv[9], nullptr, 10);
    while (h.got < count && h.cycles < limit) h.cycle(vpat.next(), rpat.next());
    // Drain: anything beyond the items sent is an extra output.
    if (h.got == count)
        for (uint64_t c = 0; c < drain; ++c) h.cycle(false, true);
    h.dut.final();
    const uint64_t stored = h.got < count ? h.got : count;
    if (!write_words(argv[2], h.out.data(), stored * kOut)) {
        std::fprintf(stderr, "harness: cannot write %s\n", argv[2]);
        return 2;
    }
    std::printf("cycles %llu in %llu out %llu hold_violations %llu extra_outputs %llu\n",
                (unsigned long long)h.cycles, (unsigned long long)h.sent, (unsigned long long)h.got,
                (unsigned long long)h.hold_violations, (unsigned long long)h.extra);
    return 0;
}
