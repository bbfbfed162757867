/* A multi-rate servo loop around robotgen's emitted C for specs/styx_multirate.yaml (Deno et al.
 * 1990, Fig 4.3): the finger PD loops (rate group 0, servo_step_g0) at 2 kHz, the feedforward and
 * computed torque above them (group 1, servo_step_g1) at 200 Hz, in a fixed-priority schedule.
 *
 *   make controller                          (builds ./examples/controller/styx_multirate)
 *   examples/controller/styx_multirate [--schedule threads|cyclic] [--cycles N] [--help]
 *
 * threads (the default): one thread per rate group, each on its own absolute schedule
 * (clock_nanosleep TIMER_ABSTIME), priorities by rate (SCHED_FIFO 80 for group 0, 79 for group 1:
 * rate-monotonic, so the fast loop preempts the slow one). Group 0 senses the simulated plant,
 * runs its step on the trajectories group 1 last published, hands the torques (its own plus group
 * 1's last) to the plant and publishes the sensed state; group 1 samples that state at its own
 * ticks, runs its step and publishes what it writes to the PD loops (held until its next
 * publication) with its torques. The two exchange through one mutex (priority inheritance): what
 * group 1 computes reaches group 0 at group 0's first tick after it is published, as on a real
 * multi-rate controller.
 *
 * cyclic: a cyclic executive, one thread at 2 kHz (SCHED_FIFO 80): at every tenth tick group 1
 * runs first, then group 0, so group 0's start is delayed by group 1's work on those ticks (its
 * jitter shows it). This is the schedule of the emitted styx_multirate_multirate_step, of the
 * Python MultiRateController and of `robotgen simulate`; its steps are called one by one here to
 * time each group.
 *
 * The plant (plant_dynamics, RK4 over one 0.5 ms period) is integrated inside this binary by the
 * fast loop. Printed at the end: the tracking error, and for each group its period jitter (the
 * call of its step minus its scheduled release, min / median / p99 / max: sensing, and in the
 * cyclic executive group 1's step, come before it) and its step's time (median and worst case). Statuses of the checked functions are honoured: a nonzero status stops with a
 * message. SCHED_FIFO and mlockall are asked for; where they are not permitted the loops run
 * anyway and say so.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

#include "styx_multirate.h"

#define NQ STYX_MULTIRATE_NQ
#define NV STYX_MULTIRATE_PLANT_DYNAMICS_V_SIZE
#define NS STYX_MULTIRATE_MULTIRATE_G1_STATE_SIZE
#define NW STYX_MULTIRATE_MULTIRATE_WR_PD_LEFT_SIZE
#define TICKS STYX_MULTIRATE_MULTIRATE_G1_TICKS
#define NS_PER_S 1000000000LL

typedef char root_velocity_is_the_box_pose_rate[NV == 3 ? 1 : -1]; /* v = (x, y, psi) rates */

static const double T0 = STYX_MULTIRATE_MULTIRATE_G0_PERIOD, T1 = STYX_MULTIRATE_MULTIRATE_G1_PERIOD;
static const double START[3] = {0.0, 0.12, 0.0}, AMP[3] = {0.01, 0.01, 0.2}, FREQ[3] = {0.5, 0.25, 0.3};

static long long now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (long long)t.tv_sec * NS_PER_S + t.tv_nsec;
}

static void sleep_until(long long at) {
    struct timespec wake = {(time_t)(at / NS_PER_S), (long)(at % NS_PER_S)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, NULL) == EINTR) {}
}

static int cmp_ll(const void *a, const void *b) {
    long long x = *(const long long *)a, y = *(const long long *)b;
    return (x > y) - (x < y);
}

static void report(const char *what, long long *v, long n) {
    qsort(v, (size_t)n, sizeof v[0], cmp_ll);
    printf("%-22s min %8.2f  median %8.2f  p99 %8.2f  max %8.2f us\n", what, v[0] / 1e3, v[n / 2] / 1e3,
           v[(long)(0.99 * (double)(n - 1))] / 1e3, v[n - 1] / 1e3);
}

static void fail(const char *fn, int status, long cycle) {
    fprintf(stderr, "styx_multirate: %s returned %d at cycle %ld (%s); stopping\n", fn, status, cycle,
            status == 1 ? "a NaN or infinite input" : "a result that is not finite");
    exit(1);
}

/* The desired box trajectory at time t (the spec's simulation section). */
static void desired(double t, double *x, double *xd, double *xdd) {
    int i;
    for (i = 0; i < 3; ++i) {
        double w = 2.0 * M_PI * FREQ[i];
        x[i] = START[i] + AMP[i] * sin(w * t);
        xd[i] = AMP[i] * w * cos(w * t);
        xdd[i] = -AMP[i] * w * w * sin(w * t);
    }
}

static void plant_step(double *theta, double *v, const double *tau, double dt, long cycle) {
    double kt[4][NQ], kv[4][NV], th[NQ], vv[NV];
    static const double c[4] = {0.0, 0.5, 0.5, 1.0};
    int s, i, status;
    for (s = 0; s < 4; ++s) {
        for (i = 0; i < NQ; ++i) th[i] = theta[i] + (s ? c[s] * dt * kt[s - 1][i] : 0.0);
        for (i = 0; i < NV; ++i) vv[i] = v[i] + (s ? c[s] * dt * kv[s - 1][i] : 0.0);
        if ((status = styx_multirate_plant_dynamics(th, vv, tau, kt[s], kv[s])) != 0) fail("plant_dynamics", status, cycle);
    }
    for (i = 0; i < NQ; ++i) theta[i] += dt / 6.0 * (kt[0][i] + 2 * kt[1][i] + 2 * kt[2][i] + kt[3][i]);
    for (i = 0; i < NV; ++i) v[i] += dt / 6.0 * (kv[0][i] + 2 * kv[1][i] + 2 * kv[2][i] + kv[3][i]);
}

/* What the two loops share, under `lock`: the sensed state group 0 publishes every tick, and what
 * group 1 publishes every one of its ticks (the trajectories it writes to the PD loops, its
 * torques). */
static struct {
    pthread_mutex_t lock;
    double theta[NQ], theta_dot[NQ];
    double wr_left[NW], wr_right[NW], tau1[NQ];
} shared;

static const styx_multirate_params params = STYX_MULTIRATE_PARAMS_DEFAULT;
static long cycles;                 /* of group 0 */
static long long origin;            /* the schedule's time 0 */
static long long *late0, *busy0, *late1, *busy1;
static long slow_cycles;
static double worst;                /* tracking error over the second half */
static double plant_theta[NQ], plant_v[NV];  /* owned by group 0 */
static double state1[NS];           /* owned by group 1 */

/* Group 1's step at its tick k on the sensed state: publishes its writes and torques; the
 * step's time [ns]. */
static long long slow_step(long k, const double *theta, const double *theta_dot, long long release) {
    double x_d[3], xd_d[3], xdd_d[3], f_e[3] = {0, 0, 0}, f_i[1] = {1.0};
    double tau1[NQ], left[NW], right[NW], next[NS];
    long long start, took;
    int status;
    desired((double)k * T1, x_d, xd_d, xdd_d);
    start = now_ns();
    late1[k] = start - release;
    status = styx_multirate_servo_step_g1(theta, theta_dot, x_d, xd_d, xdd_d, f_e, f_i, state1, &params, tau1, left,
                                          right, next);
    if (status != 0) fail("servo_step_g1", status, k);
    memcpy(state1, next, sizeof state1);
    took = now_ns() - start;
    pthread_mutex_lock(&shared.lock);
    memcpy(shared.wr_left, left, sizeof left);
    memcpy(shared.wr_right, right, sizeof right);
    memcpy(shared.tau1, tau1, sizeof tau1);
    pthread_mutex_unlock(&shared.lock);
    return took;
}

/* The sensed joint rates of the plant's state (theta_dot does not depend on tau). */
static void sense(double *theta_dot, long k) {
    double zero[NQ] = {0}, vdot[NV];
    int status = styx_multirate_plant_dynamics(plant_theta, plant_v, zero, theta_dot, vdot);
    if (status != 0) fail("plant_dynamics", status, k);
}

static void track(long k) {
    double x[3], x_d[3], xd_d[3], xdd_d[3];
    int i;
    desired((double)k * T0, x_d, xd_d, xdd_d);
    styx_multirate_plant_position(plant_theta, x);
    for (i = 0; i < 3; ++i) if (k > cycles / 2) worst = fmax(worst, fabs(x[i] - x_d[i]));
}

static void *fast_loop(void *unused) {
    double theta_dot[NQ], tau0[NQ], tau[NQ], left[NW], right[NW], tau1[NQ];
    long k;
    int i, status;
    (void)unused;
    for (k = 0; k < cycles; ++k) {
        long long release = origin + (long long)k * (long long)(T0 * NS_PER_S), start;
        sleep_until(release);
        sense(theta_dot, k);
        pthread_mutex_lock(&shared.lock);
        memcpy(shared.theta, plant_theta, sizeof plant_theta);
        memcpy(shared.theta_dot, theta_dot, sizeof theta_dot);
        memcpy(left, shared.wr_left, sizeof left);
        memcpy(right, shared.wr_right, sizeof right);
        memcpy(tau1, shared.tau1, sizeof tau1);
        pthread_mutex_unlock(&shared.lock);
        start = now_ns();
        late0[k] = start - release;
        status = styx_multirate_servo_step_g0(plant_theta, theta_dot, left, right, &params, tau0);
        if (status != 0) fail("servo_step_g0", status, k);
        for (i = 0; i < NQ; ++i) tau[i] = tau0[i] + tau1[i];
        busy0[k] = now_ns() - start;
        track(k);
        plant_step(plant_theta, plant_v, tau, T0, k);
    }
    return NULL;
}

static void *slow_loop(void *unused) {
    double theta[NQ], theta_dot[NQ];
    long k;
    (void)unused;
    for (k = 1; k < slow_cycles; ++k) {  /* tick 0 ran before the loops started */
        long long release = origin + (long long)k * (long long)(T1 * NS_PER_S);
        sleep_until(release);
        pthread_mutex_lock(&shared.lock);  /* sample what group 0 sensed last */
        memcpy(theta, shared.theta, sizeof theta);
        memcpy(theta_dot, shared.theta_dot, sizeof theta_dot);
        pthread_mutex_unlock(&shared.lock);
        busy1[k] = slow_step(k, theta, theta_dot, release);
    }
    return NULL;
}

/* Starts fn in a thread at SCHED_FIFO priority, or at normal priority where that is not
 * permitted (*fifo set to 0 then). */
static pthread_t start_thread(void *(*fn)(void *), int priority, int *fifo) {
    pthread_attr_t attr;
    struct sched_param sp = {.sched_priority = priority};
    pthread_t thread;
    int status;
    pthread_attr_init(&attr);
    if (*fifo) {
        pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
        pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
        pthread_attr_setschedparam(&attr, &sp);
    }
    status = pthread_create(&thread, &attr, fn, NULL);
    if (status == EPERM && *fifo) {
        *fifo = 0;
        pthread_attr_destroy(&attr);
        pthread_attr_init(&attr);
        status = pthread_create(&thread, &attr, fn, NULL);
    }
    pthread_attr_destroy(&attr);
    if (status != 0) {
        fprintf(stderr, "styx_multirate: pthread_create: %s\n", strerror(status));
        exit(1);
    }
    return thread;
}

static void usage(FILE *to, const char *program) {
    fprintf(to, "usage: %s [--schedule threads|cyclic] [--cycles N]\n\n"
                "The multi-rate Styx hand (specs/styx_multirate.yaml) against a simulated plant: its PD loops\n"
                "at 2 kHz, its upper levels at 200 Hz, in a fixed-priority schedule; prints the tracking\n"
                "error and each group's period jitter and servo computation's time.\n\n"
                "  --schedule S  threads (default): one thread per rate group, SCHED_FIFO by rate;\n"
                "                cyclic: one 2 kHz thread running the groups due at each tick, the slowest first\n"
                "  --cycles N    ticks of the 2 kHz group, >= 20 (default 20000)\n"
                "  -h, --help    this text\n", program);
}

int main(int argc, char **argv) {
    int i, status, threads = 1, fifo = 1;
    char *end;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) { usage(stdout, argv[0]); return 0; }
    }
    cycles = 20000;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--schedule") == 0 || strcmp(argv[i], "--cycles") == 0) {
            if (i + 1 >= argc) {
                fprintf(stderr, "styx_multirate: %s needs a value\n", argv[i]);
                return 2;
            }
            if (strcmp(argv[i], "--schedule") == 0) {
                ++i;
                if (strcmp(argv[i], "threads") != 0 && strcmp(argv[i], "cyclic") != 0) {
                    fprintf(stderr, "styx_multirate: --schedule takes threads or cyclic, got '%s'\n", argv[i]);
                    return 2;
                }
                threads = strcmp(argv[i], "threads") == 0;
            } else {
                ++i;
                errno = 0;
                cycles = strtol(argv[i], &end, 10);
                if (end == argv[i] || *end != '\0' || errno != 0 || cycles < 20) {
                    fprintf(stderr, "styx_multirate: --cycles takes an integer >= 20, got '%s'\n", argv[i]);
                    return 2;
                }
            }
        } else {
            fprintf(stderr, "styx_multirate: unknown argument '%s'\n", argv[i]);
            usage(stderr, argv[0]);
            return 2;
        }
    }
    slow_cycles = (cycles + TICKS - 1) / TICKS;
    late0 = malloc((size_t)cycles * sizeof *late0);
    busy0 = malloc((size_t)cycles * sizeof *busy0);
    late1 = calloc((size_t)slow_cycles, sizeof *late1);
    busy1 = calloc((size_t)slow_cycles, sizeof *busy1);
    if (late0 == NULL || busy0 == NULL || late1 == NULL || busy1 == NULL) {
        fprintf(stderr, "styx_multirate: out of memory\n");
        return 1;
    }
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
        printf("note: mlockall not permitted (%s): pages may fault during the loop\n", strerror(errno));

    /* the plant on the desired path, moving with it (v: the box's velocity) */
    if ((status = styx_multirate_plant_inverse(START, plant_theta)) != 0) fail("plant_inverse", status, 0);
    {
        double x_d[3], xdd_d[3];
        desired(0.0, x_d, plant_v, xdd_d);
    }

    if (threads) {
        pthread_t fast, slow;
        pthread_mutexattr_t m;
        double theta_dot[NQ];
        pthread_mutexattr_init(&m);
        pthread_mutexattr_setprotocol(&m, PTHREAD_PRIO_INHERIT);
        pthread_mutex_init(&shared.lock, &m);
        sense(theta_dot, 0);
        memcpy(shared.theta, plant_theta, sizeof plant_theta);
        memcpy(shared.theta_dot, theta_dot, sizeof theta_dot);
        if ((status = styx_multirate_servo_init_g1(plant_theta, theta_dot, state1)) != 0) fail("servo_init_g1", status, 0);
        busy1[0] = slow_step(0, plant_theta, theta_dot, now_ns());  /* group 1's tick 0, before the loops start */
        origin = now_ns() + (long long)(T0 * NS_PER_S);
        slow = start_thread(slow_loop, 79, &fifo);
        fast = start_thread(fast_loop, 80, &fifo);
        pthread_join(fast, NULL);
        pthread_join(slow, NULL);
        printf("%ld cycles at %.0f Hz and %ld at %.0f Hz, one thread per rate group (%s)\n", cycles, 1 / T0,
               slow_cycles, 1 / T1, fifo ? "SCHED_FIFO 80 and 79" : "normal priority: SCHED_FIFO not permitted");
    } else {
        /* the cyclic executive: every tick, the groups due run in one thread, group 1 first (what it
         * writes is held for group 0 from this tick on). styx_multirate_multirate_step does the same
         * in one call; the steps are called one by one here to time each group. */
        struct sched_param sp = {.sched_priority = 80};
        double theta_dot[NQ], tau0[NQ], tau1[NQ] = {0}, tau[NQ], left[NW], right[NW], x_d[3], xd_d[3], xdd_d[3];
        double f_e[3] = {0, 0, 0}, f_i[1] = {1.0}, next[NS];
        long k;
        if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) fifo = 0;
        origin = now_ns() + (long long)(T0 * NS_PER_S);
        for (k = 0; k < cycles; ++k) {
            long long release = origin + (long long)k * (long long)(T0 * NS_PER_S), start;
            sleep_until(release);
            start = now_ns();
            sense(theta_dot, k);
            if (k % TICKS == 0) {
                if (k == 0 && (status = styx_multirate_servo_init_g1(plant_theta, theta_dot, state1)) != 0)
                    fail("servo_init_g1", status, k);
                desired((double)k * T0, x_d, xd_d, xdd_d);
                start = now_ns();
                late1[k / TICKS] = start - release;
                status = styx_multirate_servo_step_g1(plant_theta, theta_dot, x_d, xd_d, xdd_d, f_e, f_i, state1, &params,
                                                      tau1, left, right, next);
                if (status != 0) fail("servo_step_g1", status, k);
                memcpy(state1, next, sizeof state1);
                busy1[k / TICKS] = now_ns() - start;
            }
            start = now_ns();
            late0[k] = start - release;
            status = styx_multirate_servo_step_g0(plant_theta, theta_dot, left, right, &params, tau0);
            if (status != 0) fail("servo_step_g0", status, k);
            for (i = 0; i < NQ; ++i) tau[i] = tau0[i] + tau1[i];
            busy0[k] = now_ns() - start;
            track(k);
            plant_step(plant_theta, plant_v, tau, T0, k);
        }
        printf("%ld cycles at %.0f Hz and %ld at %.0f Hz, a cyclic executive (%s)\n", cycles, 1 / T0, slow_cycles,
               1 / T1, fifo ? "SCHED_FIFO 80" : "normal priority: SCHED_FIFO not permitted");
    }
    printf("tracking error, second half: max %.3e (rad or m)\n", worst);
    report("g0 period jitter", late0, cycles);
    report("g0 servo computation", busy0, cycles);
    report("g1 period jitter", late1 + 1, slow_cycles - 1);
    report("g1 servo computation", busy1, slow_cycles);
    free(late0);
    free(busy0);
    free(late1);
    free(busy1);
    return 0;
}
