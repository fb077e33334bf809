/* The command effects' per-substep recursions, compiled (rover_env.effects.native).
 *
 * Each loop is the Python float loop it replaces, operation for operation: built with
 * -ffp-contract=off (no fused multiply-add) on IEEE doubles, it gives the same numbers to
 * the bit (tests/test_command_sequence.py runs both). Arrays are C-ordered rows of m columns.
 */

/* A first-order lag over n substeps: x <- u + (x - u) * a per column; out[k] is x after
 * substep k; x (m) holds the state in and out. */
void lag_sequence(const double *u, long n, long m, double a, double *x, double *out) {
    for (long j = 0; j < m; j++) {
        double xi = x[j];
        for (long k = 0; k < n; k++) {
            double ui = u[k * m + j];
            xi = ui + (xi - ui) * a;
            out[k * m + j] = xi;
        }
        x[j] = xi;
    }
}

/* A lag primed from rest over n held samples: x <- c + (x - c) * f[k] per column, from 0. */
void lag_prime(const double *c, const double *f, long n, long m, double *x) {
    for (long j = 0; j < m; j++) {
        double xi = 0.0;
        for (long k = 0; k < n; k++) {
            double ci = c[k * m + j];
            xi = ci + (xi - ci) * f[k];
        }
        x[j] = xi;
    }
}
