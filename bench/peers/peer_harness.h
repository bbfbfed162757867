/* The table bench/peers/harness.py writes (calls.c) and bench/peers/peer_harness.c times. */
#ifndef PEER_HARNESS_H
#define PEER_HARNESS_H

struct peer_entry {
    const char *kernel;  /* robotgen's name of what it computes: mass, inverse_dynamics, ... */
    const char *who;     /* robotgen, pinocchio_cg, casadi_kin_dyn */
    const char *variant; /* the peer's function (robotgen: its kernel) */
    void (*call)(const double *x, double *out); /* x = [q, qd, qdd or tau] */
    int outputs;         /* doubles written to out */
};

extern const struct peer_entry PEER_ENTRIES[];
extern const int PEER_ENTRIES_COUNT;

#endif
