/* dkrrt-plan-cabi: the checks of `dkrrt plan`, for reference planners (C ABI).
 * Build: cargo build --release -p dkrrt-plan-cabi   (target/release/libdkrrt_plan_cabi.a)
 * Link:  -ldkrrt_plan_cabi -lpthread -ldl -lm
 * Every function refuses null arguments (-1) and never dereferences them. A handle is used
 * by one thread at a time (it holds the checker's buffers and counters). */
#ifndef DKRRT_PLAN_H
#define DKRRT_PLAN_H
#include <stddef.h>
#include <stdint.h>
#ifdef __cplusplus
extern "C" {
#endif

#define DK_NJ 6

typedef struct DkProblem DkProblem;

typedef struct {
    double start[DK_NJ], goal[DK_NJ], q_min[DK_NJ], q_max[DK_NJ];
    double time_limit_s;
    uint64_t seed;
    int still;            /* 1: nothing moves and start/goal leave delta/2: joint-space planning applies */
    double start_clear_m; /* < 0: in collision */
    double goal_clear_m;
    double delta_m;       /* the checks' delta */
} DkInfo;

typedef struct {
    uint64_t states, segments, configs; /* calls of dk_state_clear, dk_segment_clear; samples measured */
    double check_s;                      /* time inside those two calls */
} DkCounts;

/* NULL on error, with the message (file and field) in err (err_len bytes, NUL-terminated). */
DkProblem *dk_problem_open(const char *path, double time_limit_s, char *err, size_t err_len);
void dk_problem_close(DkProblem *h);
int dk_problem_info(const DkProblem *h, DkInfo *out);
/* 1 clear, 0 not, -1 null argument. */
int dk_state_clear(DkProblem *h, const double *q);
int dk_segment_clear(DkProblem *h, const double *a, const double *b);
/* Duration [s] of the waypoints timed as dkrrt times its own; -1 bad argument, -2 cannot be timed.
   *min_clearance_m: the smallest clearance on its 1 ms grid, INFINITY when nothing came within 100 m. */
double dk_path_duration(DkProblem *h, const double *path, size_t n, double *min_clearance_m, int *passed);
int dk_problem_counts(const DkProblem *h, DkCounts *out);

#ifdef __cplusplus
}
#endif
#endif
