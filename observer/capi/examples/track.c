/* Runs greybox-observer's MRAS or Kalman filter over a drive log through the C ABI and
 * prints the final estimates as `greybox track` prints them (its summary line):
 *
 *   track LOG.csv N_P L_S K_E0 R_S0 [mras|ekf] [f64|f32] [L_Q]
 *
 * L_Q: a salient machine's q-axis inductance [H] (L_S is then L_d; the `_init_salient`
 * functions, greybox track's --l-q).
 * LOG.csv: a plain CSV with a header naming t, ud, uq, id, iq, w_m (greybox's standard
 * columns; others ignored). Each sample is (i_d[k], i_q[k], u_d[k], u_q[k],
 * (w_m[k] + w_m[k+1])/2), as `greybox track` forms it; the filter's current noise is the
 * log's (the median of the currents' second differences, `greybox::online::current_noise`).
 * Built and run in CI (.ci/run) against `greybox track` on the repository's sample log. */
#include "greybox_observer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { T, UD, UQ, ID, IQ, WM, NCOL };
static const char *NAMES[NCOL] = {"t", "ud", "uq", "id", "iq", "w_m"};

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* greybox::online::current_noise: 1.4826 median|second difference| / sqrt(6), floored. */
static double current_noise(const double *i_d, const double *i_q, size_t n) {
    double sum = 0.0;
    for (size_t k = 0; k < n; k++) sum += i_d[k] * i_d[k];
    for (size_t k = 0; k < n; k++) sum += i_q[k] * i_q[k];
    double rms = n > 0 ? sqrt(sum / (double)(2 * n)) : 0.0;
    double floor = fmax(1e-6 * rms, 1e-9);
    if (n < 3) return floor;
    size_t m = 2 * (n - 2);
    double *d2 = malloc(m * sizeof *d2);
    if (!d2) return floor;
    for (size_t k = 0; k + 2 < n; k++) d2[k] = fabs(i_d[k + 2] - 2.0 * i_d[k + 1] + i_d[k]);
    for (size_t k = 0; k + 2 < n; k++) d2[n - 2 + k] = fabs(i_q[k + 2] - 2.0 * i_q[k + 1] + i_q[k]);
    qsort(d2, m, sizeof *d2, cmp);
    double sigma = 1.4826 * d2[m / 2] / sqrt(6.0);
    free(d2);
    return fmax(sigma, floor);
}

/* Rust's `{:.2e}`: 9.57e-5, not C's 9.57e-05. */
static void sci(char *buf, size_t len, double v) {
    char tmp[40];
    snprintf(tmp, sizeof tmp, "%.2e", v);
    char *e = strchr(tmp, 'e');
    if (!e) {
        snprintf(buf, len, "%s", tmp);
        return;
    }
    *e = '\0';
    snprintf(buf, len, "%se%d", tmp, atoi(e + 1));
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s LOG.csv N_P L_S K_E0 R_S0 [mras|ekf] [f64|f32] [L_Q]\n", argv[0]);
        return 2;
    }
    const char *path = argv[1];
    int ekf = argc > 6 && strcmp(argv[6], "ekf") == 0;
    int single = argc > 7 && strcmp(argv[7], "f32") == 0;
    double l_q = argc > 8 ? atof(argv[8]) : 0.0; /* 0: surface magnets */
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "%s: cannot open\n", path);
        return 2;
    }
    static char line[1 << 16];
    int col[NCOL];
    for (int c = 0; c < NCOL; c++) col[c] = -1;
    if (!fgets(line, sizeof line, f)) return 2;
    line[strcspn(line, "\r\n")] = '\0';
    int j = 0;
    for (char *tok = strtok(line, ","); tok; tok = strtok(NULL, ","), j++)
        for (int c = 0; c < NCOL; c++)
            if (strcmp(tok, NAMES[c]) == 0) col[c] = j;
    for (int c = 0; c < NCOL; c++)
        if (col[c] < 0) {
            fprintf(stderr, "%s: no column %s\n", path, NAMES[c]);
            return 2;
        }
    size_t cap = 1024, n = 0;
    double *v[NCOL];
    for (int c = 0; c < NCOL; c++) v[c] = malloc(cap * sizeof(double));
    while (fgets(line, sizeof line, f)) {
        if (n == cap) {
            cap *= 2;
            for (int c = 0; c < NCOL; c++) v[c] = realloc(v[c], cap * sizeof(double));
        }
        char *p = line;
        for (int k = 0; *p && *p != '\n'; k++) {
            char *end;
            double x = strtod(p, &end);
            for (int c = 0; c < NCOL; c++)
                if (col[c] == k) v[c][n] = x;
            p = strchr(end, ',');
            if (!p) break;
            p++;
        }
        n++;
    }
    fclose(f);
    if (n < 2) {
        fprintf(stderr, "%s: fewer than two samples\n", path);
        return 2;
    }
    double h = (v[T][n - 1] - v[T][0]) / (double)(n - 1);

    size_t steps = n - 1;
    double sigma_i = current_noise(v[ID], v[IQ], n);
    uint32_t n_p = (uint32_t)atoi(argv[2]);
    GbEstimatesF64 e = {0};
    int rc;
    if (!single) {
        GbSettingsF64 s;
        gb_settings_f64_default(n_p, atof(argv[3]), h, &s);
        s.adaptation = ADAPTATION_NORMALISED; /* greybox track's --adaptation default */
        s.k_e0 = atof(argv[4]);
        s.r_s0 = atof(argv[5]);
        GbMrasF64 mras;
        GbKalmanF64 kf;
        GbNoiseF64 noise;
        gb_noise_f64_for_machine(sigma_i, s.r_s0, s.k_e0, &noise);
        if (l_q > 0.0)
            rc = ekf ? gb_kalman_f64_init_salient(&kf, &s, l_q, &noise) : gb_mras_f64_init_salient(&mras, &s, l_q);
        else
            rc = ekf ? gb_kalman_f64_init(&kf, &s, &noise) : gb_mras_f64_init(&mras, &s);
        for (size_t k = 0; rc == GB_OK && k < steps; k++) {
            GbSampleF64 x = {v[ID][k], v[IQ][k], v[UD][k], v[UQ][k], 0.5 * (v[WM][k] + v[WM][k + 1])};
            rc = ekf ? gb_kalman_f64_update(&kf, &x, &e) : gb_mras_f64_update(&mras, &x, &e);
        }
    } else {
        /* The same in float: the samples rounded to float, the estimates widened back. */
        GbSettingsF32 s;
        gb_settings_f32_default(n_p, (float)atof(argv[3]), (float)h, &s);
        s.adaptation = ADAPTATION_NORMALISED;
        s.k_e0 = (float)atof(argv[4]);
        s.r_s0 = (float)atof(argv[5]);
        GbMrasF32 mras;
        GbKalmanF32 kf;
        GbNoiseF32 noise;
        gb_noise_f32_for_machine((float)sigma_i, s.r_s0, s.k_e0, &noise);
        if (l_q > 0.0)
            rc = ekf ? gb_kalman_f32_init_salient(&kf, &s, (float)l_q, &noise)
                     : gb_mras_f32_init_salient(&mras, &s, (float)l_q);
        else
            rc = ekf ? gb_kalman_f32_init(&kf, &s, &noise) : gb_mras_f32_init(&mras, &s);
        GbEstimatesF32 e32 = {0};
        for (size_t k = 0; rc == GB_OK && k < steps; k++) {
            GbSampleF32 x = {(float)v[ID][k], (float)v[IQ][k], (float)v[UD][k], (float)v[UQ][k],
                             (float)(0.5 * (v[WM][k] + v[WM][k + 1]))};
            rc = ekf ? gb_kalman_f32_update(&kf, &x, &e32) : gb_mras_f32_update(&mras, &x, &e32);
        }
        e.k_e = e32.k_e, e.k_t = e32.k_t, e.r_s = e32.r_s, e.k_e_se = e32.k_e_se, e.r_s_se = e32.r_s_se;
    }
    if (rc != GB_OK) {
        fprintf(stderr, "%s\n", gb_error_name(rc));
        return 1;
    }
    double t_end = v[T][0] + (double)(steps - 1) * h;
    if (ekf) {
        char k_se[80], t_se[80], r_se[80];
        sci(k_se, sizeof k_se, 1.96 * e.k_e_se);
        sci(t_se, sizeof t_se, 1.96 * (sqrt(1.5) * e.k_e_se));
        sci(r_se, sizeof r_se, 1.96 * e.r_s_se);
        printf("%s: K_e = %.6f \xc2\xb1 %s V s/rad, K_t = %.6f \xc2\xb1 %s N m/A, R_s = %.6f \xc2\xb1 %s ohm "
               "(95 %%; %zu filter steps, to t = %.4f s)\n",
               path, e.k_e, k_se, e.k_t, t_se, e.r_s, r_se, steps, t_end);
    } else {
        printf("%s: K_e = %.6f V s/rad, K_t = %.6f N m/A, R_s = %.6f ohm (%zu observer steps, to t = %.4f s)\n",
               path, e.k_e, e.k_t, e.r_s, steps, t_end);
    }
    return 0;
}
