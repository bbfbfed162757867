/* Timing harness for robotgen's kernels against the code-generating peers' (bench/peers/).
 *
 * bench/peers/harness.py writes calls.c for one robot: PEER_ENTRIES, one per (kernel, who,
 * variant), each a function call(x, out) that calls robotgen's kernel or a peer's generated
 * function on the packed state x = [q, qd, qdd or tau] and writes out. Every entry is called the
 * same way (through the table's pointer, from another translation unit), so calling costs the
 * same on both sides. Compiled with the kernels' flags, as bench/harness.c is:
 *   cc -std=c99 -O2 -ffp-contract=off -DRG_NQ=6 peer_harness.c calls.c <kernels and peers' C> -lm
 *
 *   harness [KERNEL ...]   for each kernel, its entries in interleaved rounds: each of REPEATS
 *                          rounds times every entry once, the order turned by one entry per
 *                          round, so that a disturbance of the machine falls on all of them;
 *                          prints "kernel who variant min_ns median_ns iterations"
 *   harness dump FILE      every entry's outputs on every state, raw doubles, entries in table
 *                          order (the states first), for the agreement check
 *
 * The states and the timed loop are bench/harness.c's: NSETS random states from the same LCG
 * (angles in [-pi, pi], rates in [-2, 2]) cycled through, one output element per call summed
 * into a volatile sink, each loop calibrated to >= 50 ms, min and median of REPEATS.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "peer_harness.h"

#define NQ RG_NQ
#define NSETS 256 /* power of two */
#define REPEATS 7
#define MIN_NS 5.0e7

static double X[NSETS][3 * NQ];
static double OUT[8 * NQ * NQ + 8 * NQ + 16];
static volatile double sink;

static double now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static unsigned long long lcg_state = 88172645463325252ULL;
static double uniform(double lo, double hi) {
    lcg_state = lcg_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return lo + (hi - lo) * (double)(lcg_state >> 11) * (1.0 / 9007199254740992.0);
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* ns per call of ITERS calls of entry E on the states in turn */
static double timed(const struct peer_entry *e, long iters) {
    double acc = 0.0, t0, t1;
    long it;
    t0 = now_ns();
    for (it = 0; it < iters; it++) {
        e->call(X[it & (NSETS - 1)], OUT);
        acc += OUT[it % e->outputs];
    }
    t1 = now_ns();
    sink += acc;
    return (t1 - t0) / (double)iters;
}

static void time_kernel(const char *kernel) {
    const struct peer_entry *entries[64];
    long iters[64];
    double times[64][REPEATS];
    int n = 0, i, r;
    for (i = 0; i < PEER_ENTRIES_COUNT && n < 64; i++)
        if (strcmp(PEER_ENTRIES[i].kernel, kernel) == 0) entries[n++] = &PEER_ENTRIES[i];
    for (i = 0; i < n; i++) { /* calibrate: each loop takes >= MIN_NS */
        iters[i] = 1000;
        while (timed(entries[i], iters[i]) * (double)iters[i] < MIN_NS && iters[i] < (1L << 30)) iters[i] *= 2;
    }
    for (r = 0; r < REPEATS; r++)
        for (i = 0; i < n; i++) {
            int k = (i + r) % n;
            times[k][r] = timed(entries[k], iters[k]);
        }
    for (i = 0; i < n; i++) {
        qsort(times[i], REPEATS, sizeof times[i][0], cmp_double);
        printf("%s %s %s %.3f %.3f %ld\n", kernel, entries[i]->who, entries[i]->variant, times[i][0],
               times[i][REPEATS / 2], iters[i]);
        fflush(stdout);
    }
}

static int dump(const char *path) {
    FILE *f = fopen(path, "wb");
    int i, s;
    if (!f) {
        perror(path);
        return 1;
    }
    fwrite(X, sizeof X[0], NSETS, f);
    for (i = 0; i < PEER_ENTRIES_COUNT; i++)
        for (s = 0; s < NSETS; s++) {
            PEER_ENTRIES[i].call(X[s], OUT);
            fwrite(OUT, sizeof OUT[0], (size_t)PEER_ENTRIES[i].outputs, f);
        }
    return fclose(f) != 0;
}

int main(int argc, char **argv) {
    int s, i;
    for (s = 0; s < NSETS; s++) /* bench/harness.c's order: q, qd, qdd of each state in turn */
        for (i = 0; i < NQ; i++) {
            X[s][i] = uniform(-3.141592653589793, 3.141592653589793);
            X[s][NQ + i] = uniform(-2.0, 2.0);
            X[s][2 * NQ + i] = uniform(-2.0, 2.0);
        }
    if (argc == 3 && strcmp(argv[1], "dump") == 0) return dump(argv[2]);
    if (argc > 1) {
        for (i = 1; i < argc; i++) time_kernel(argv[i]);
    } else {
        for (i = 0; i < PEER_ENTRIES_COUNT; i++) {
            int seen = 0, j;
            for (j = 0; j < i; j++) seen |= strcmp(PEER_ENTRIES[j].kernel, PEER_ENTRIES[i].kernel) == 0;
            if (!seen) time_kernel(PEER_ENTRIES[i].kernel);
        }
    }
    return sink == 12345.678 ? 1 : 0; /* use sink so it is observable */
}
