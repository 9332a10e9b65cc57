// soc_harness.cpp -- Verilator driver of ik5r.hdl.soc.SoC (top module ik5r_soc): runs one job.
//
// Usage: soc_harness IN.bin OUT.bin. IN (little-endian uint32 words): magic 0x4B523549 ("I5RK"),
// image words, job word index, job words, first output word (from the job start), output words,
// cycle limit (low, high), then the image and the job. The RAM is loaded through the host port
// with the CPU held, the CPU released, and every clock counted until the STOP register is
// written or the cycle limit is reached; then the output words are read back.
// OUT: status (0 stopped, 1 cycle limit reached), stop code, cycles (low, high), retired
// instructions (low, high), number of MARK writes, then per MARK: cycle (low, high), retired
// instructions before it (low, high), value; then the output words.
#include <cstdint>
#include <cstdio>
#include <vector>

#include "Vik5r_soc.h"
#include "Vik5r_soc__Syms.h"
#include "Vik5r_soc___024root.h"
#include "verilated.h"

namespace {

struct Mark {
    uint64_t cycle, instret;
    uint32_t value;
};

bool read_words(const char *path, std::vector<uint32_t> &words) {
    FILE *f = std::fopen(path, "rb");
    if (!f) return false;
    uint32_t w;
    while (std::fread(&w, 4, 1, f) == 1) words.push_back(w);
    std::fclose(f);
    return true;
}

class Soc {
  public:
    explicit Soc(VerilatedContext *ctx) : top(new Vik5r_soc{ctx}) {}
    ~Soc() { top->final(); delete top; }
    void tick() {
        top->clk = 0;
        top->eval();
        top->clk = 1;
        top->eval();
    }
    void write(uint32_t addr, uint32_t data) {
        top->host_addr = addr;
        top->host_wdata = data;
        top->host_we = 1;
        tick();
        top->host_we = 0;
    }
    uint32_t read(uint32_t addr) {
        top->host_addr = addr;
        tick();
        top->eval();
        return top->host_rdata;
    }
    bool retiring() const { // lastStageIsFiring: an instruction leaves the last stage (/* verilator public */ in the wheel).
        return top->rootp->vlSymsp->TOP__ik5r_soc__cpu.lastStageIsFiring; }
    Vik5r_soc *top;
};

}  // namespace

int main(int argc, char **argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s IN.bin OUT.bin\n", argv[0]);
        return 2;
    }
    std::vector<uint32_t> in;
    if (!read_words(argv[1], in) || in.size() < 8 || in[0] != 0x4B523549u) {
        std::fprintf(stderr, "%s: not a job file\n", argv[1]);
        return 2;
    }
    const uint32_t n_image = in[1], job_word = in[2], n_job = in[3], out_first = in[4], n_out = in[5];
    const uint64_t limit = in[6] | (uint64_t)in[7] << 32;
    if (in.size() != 8ull + n_image + n_job) {
        std::fprintf(stderr, "%s: %zu words, header says %llu\n", argv[1], in.size(),
                     8ull + n_image + n_job);
        return 2;
    }
    VerilatedContext ctx;
    Soc soc(&ctx);
    soc.top->rst = 1;
    soc.top->hold = 1;
    for (int i = 0; i < 4; i++) soc.tick();
    soc.top->rst = 0;
    for (uint32_t i = 0; i < n_image; i++) soc.write(i, in[8 + i]);
    for (uint32_t i = 0; i < n_job; i++) soc.write(job_word + i, in[8 + n_image + i]);
    soc.top->hold = 0;
    std::vector<Mark> marks;
    uint64_t cycle = 0, instret = 0;
    while (!soc.top->stop && cycle < limit) {
        soc.tick();
        cycle++;
        if (soc.retiring()) instret++;
        if (soc.top->mark) marks.push_back({cycle, instret, soc.top->mark_value});
    }
    const uint32_t status = soc.top->stop ? 0 : 1, code = soc.top->stop_code;
    soc.top->hold = 1;
    soc.tick();
    std::vector<uint32_t> out = {status, code, (uint32_t)cycle, (uint32_t)(cycle >> 32),
                                 (uint32_t)instret, (uint32_t)(instret >> 32),
                                 (uint32_t)marks.size()};
    for (const Mark &m : marks) {
        out.insert(out.end(), {(uint32_t)m.cycle, (uint32_t)(m.cycle >> 32), (uint32_t)m.instret,
                               (uint32_t)(m.instret >> 32), m.value});
    }
    for (uint32_t i = 0; i < n_out; i++) out.push_back(soc.read(job_word + out_first + i));
    FILE *f = std::fopen(argv[2], "wb");
    if (!f || std::fwrite(out.data(), 4, out.size(), f) != out.size()) {
        std::fprintf(stderr, "%s: cannot write\n", argv[2]);
        return 2;
    }
    std::fclose(f);
    return 0;
}
