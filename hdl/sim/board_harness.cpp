// board_harness.cpp -- Verilator driver of ik5r.hdl.board.top.BoardLink (top module ik5r_board):
// the board's UART pins bridged to a TCP socket, so the real host client (pyserial URL
// socket://127.0.0.1:PORT) talks to the simulated board.
//
// Usage: board_harness CLOCKS_PER_BIT PORT STATS.txt [RESET_AFTER_BYTES]
// Listens on 127.0.0.1:PORT (0: any free port; the port is printed as "port N" on stdout),
// serves one connection and exits when it closes. Bytes from the socket are sent into `rx` as
// 8N1 at CLOCKS_PER_BIT clocks a bit; bits on `tx` are sampled mid-bit and the bytes sent back.
// With RESET_AFTER_BYTES, `rst` is held for 4 clocks once that many bytes went in (a board reset
// mid-stream). Simulated time follows the data: when no byte waits to go in, the harness waits
// up to 1 ms of wall time for the host every 64 clocks, so the host's own speed (a Python
// process on a shared machine) does not show as idle line time: the simulated line runs as it
// would with a host that always has the next pose ready. STATS: "cycles C first_rx F last_tx L bytes_in I bytes_out O resets R".
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <vector>

#include "Vik5r_board.h"
#include "verilated.h"

namespace {

struct LineIn {  // host -> board: 8N1 onto rx
    std::deque<uint8_t> queue;
    int bit = -1, clocks = 0;
    uint16_t frame = 0;
    bool idle() const { return bit < 0 && queue.empty(); }
    // The level of rx this clock; true when a byte was started.
    bool step(int cpb, uint8_t &level) {
        bool started = false;
        if (bit < 0 && !queue.empty()) {
            frame = (uint16_t)(queue.front() << 1 | 0x200);
            queue.pop_front();
            bit = 0;
            clocks = 0;
            started = true;
        }
        level = bit < 0 ? 1 : (frame >> bit) & 1;
        if (bit >= 0 && ++clocks == cpb) {
            clocks = 0;
            if (++bit == 10) bit = -1;
        }
        return started;
    }
};

struct LineOut {  // board -> host: tx sampled mid-bit
    int count = -1, clocks = 0;
    uint16_t bits = 0;
    uint8_t last = 1;
    // A received byte in `byte`: returns true.
    bool step(int cpb, uint8_t level, uint8_t &byte) {
        bool done = false;
        if (count < 0) {
            if (last && !level) { count = 0; clocks = cpb / 2; }
        } else if (--clocks == 0) {
            bits = (uint16_t)(bits >> 1 | level << 9);
            clocks = cpb;
            if (++count == 10) {
                count = -1;
                if ((bits & 0x200) && !(bits & 1)) { byte = (uint8_t)(bits >> 1); done = true; }
            }
        }
        last = level;
        return done;
    }
};

int listen_on(int port) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons((uint16_t)port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(fd, (sockaddr *)&addr, sizeof addr) != 0 || listen(fd, 1) != 0) return -1;
    socklen_t len = sizeof addr;
    getsockname(fd, (sockaddr *)&addr, &len);
    std::printf("port %d\n", ntohs(addr.sin_port));
    std::fflush(stdout);
    return fd;
}

// Reads what the host sent (waiting up to `ms`); false once the connection closed.
bool receive(int fd, LineIn &in, int ms) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, ms) <= 0) return true;
    uint8_t buf[4096];
    ssize_t n = recv(fd, buf, sizeof buf, 0);
    if (n <= 0) return false;
    in.queue.insert(in.queue.end(), buf, buf + n);
    return true;
}

}  // namespace

int main(int argc, char **argv) {
    if (argc < 4) {
        std::fprintf(stderr, "usage: %s CLOCKS_PER_BIT PORT STATS.txt [RESET_AFTER_BYTES]\n", argv[0]);
        return 2;
    }
    const int cpb = std::atoi(argv[1]);
    const long long reset_after = argc > 4 ? std::atoll(argv[4]) : -1;
    int server = listen_on(std::atoi(argv[2]));
    if (cpb < 4 || server < 0) {
        std::fprintf(stderr, "board_harness: bad clocks per bit or cannot listen\n");
        return 2;
    }
    int fd = accept(server, nullptr, nullptr);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    VerilatedContext ctx;
    Vik5r_board top{&ctx};
    top.rx = 1;
    top.rst = 1;
    LineIn in;
    LineOut out;
    std::vector<uint8_t> pending;
    uint64_t cycle = 0, first_rx = 0, last_tx = 0, bytes_in = 0, bytes_out = 0, resets = 0;
    int reset_clocks = 4;
    bool open = true;
    while (open || !pending.empty()) {
        if (cycle % 64 == 0) {
            if (open) open = receive(fd, in, in.idle() ? 1 : 0);
            if (!pending.empty()) {
                if (send(fd, pending.data(), pending.size(), MSG_NOSIGNAL) < 0) open = false;
                pending.clear();
            }
            if (!open) break;
        }
        uint8_t level;
        if (in.step(cpb, level)) {
            if (!bytes_in) first_rx = cycle;
            if ((long long)++bytes_in == reset_after) { reset_clocks = 4; resets++; }
        }
        top.rx = level;
        top.rst = reset_clocks > 0;
        if (reset_clocks > 0) reset_clocks--;
        top.clk = 0;
        top.eval();
        top.clk = 1;
        top.eval();
        cycle++;
        uint8_t byte;
        if (out.step(cpb, top.tx, byte)) {
            pending.push_back(byte);
            bytes_out++;
            last_tx = cycle;
        }
    }
    top.final();
    close(fd);
    close(server);
    FILE *f = std::fopen(argv[3], "w");
    if (!f) return 2;
    std::fprintf(f, "cycles %llu first_rx %llu last_tx %llu bytes_in %llu bytes_out %llu resets %llu\n",
                 (unsigned long long)cycle, (unsigned long long)first_rx, (unsigned long long)last_tx,
                 (unsigned long long)bytes_in, (unsigned long long)bytes_out, (unsigned long long)resets);
    std::fclose(f);
    return 0;
}
