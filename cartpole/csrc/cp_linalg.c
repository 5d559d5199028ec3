/* cp_linalg.c: small dense linear algebra (declared in cp_linalg.h). */
#include <math.h>

#include "cp_common.h"
#include "cp_linalg.h"

void la_mul_strided(const cp_real* A, const cp_real* B, cp_real* C, int n, int m, int p, int bk, int bj)
{
    int i, j, k;
    cp_real acc;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            acc = 0;
            for (k = 0; k < m; ++k) {
                acc += A[i * m + k] * B[k * bk + j * bj];
            }
            C[i * p + j] = acc;
        }
    }
}

int la_right_solve(cp_real* Sm, const cp_real* B, cp_real* X, int n, int r)
{
    int i, j, k, piv;
    cp_real big, f, tmp;
    int perm[CP_NY];
    cp_real col[CP_NY];
    for (i = 0; i < n; ++i) {
        perm[i] = i;
    }
    for (k = 0; k < n; ++k) {
        piv = k;
        big = CP_FABS(Sm[k * n + k]);
        for (i = k + 1; i < n; ++i) {
            if (CP_FABS(Sm[i * n + k]) > big) {
                big = CP_FABS(Sm[i * n + k]);
                piv = i;
            }
        }
        if (big == 0) {
            return 1;
        }
        if (piv != k) {
            for (j = 0; j < n; ++j) {
                tmp = Sm[k * n + j];
                Sm[k * n + j] = Sm[piv * n + j];
                Sm[piv * n + j] = tmp;
            }
            i = perm[k];
            perm[k] = perm[piv];
            perm[piv] = i;
        }
        for (i = k + 1; i < n; ++i) {
            f = Sm[i * n + k] / Sm[k * n + k];
            Sm[i * n + k] = f;
            for (j = k + 1; j < n; ++j) {
                Sm[i * n + j] -= f * Sm[k * n + j];
            }
        }
    }
    for (j = 0; j < r; ++j) { /* column j of X' solves S c = B[j, :]' */
        for (i = 0; i < n; ++i) {
            col[i] = B[j * n + perm[i]];
        }
        for (i = 0; i < n; ++i) {
            for (k = 0; k < i; ++k) {
                col[i] -= Sm[i * n + k] * col[k];
            }
        }
        for (i = n - 1; i >= 0; --i) {
            for (k = i + 1; k < n; ++k) {
                col[i] -= Sm[i * n + k] * col[k];
            }
            col[i] /= Sm[i * n + i];
        }
        for (i = 0; i < n; ++i) {
            X[j * n + i] = col[i];
        }
    }
    return 0;
}
