/* cp_linalg.h: small dense linear algebra of the EKF and MHE parts (row-major, sizes as arguments;
 * cartpole/csrc/cp_linalg.c). */
#ifndef CP_LINALG_H
#define CP_LINALG_H

#include "cp_config.h"

/* C (n x p) = A B with A (n x m) and B's entry (k, j) at B[k * bk + j * bj] */
void la_mul_strided(const cp_real* A, const cp_real* B, cp_real* C, int n, int m, int p, int bk, int bj);
/* C = A B with A (n x m), B (m x p) */
#define la_mul(A, B, C, n, m, p) la_mul_strided((A), (B), (C), (n), (m), (p), (p), 1)
/* C = A B' with A (n x m), B (p x m) */
#define la_mul_t(A, B, C, n, m, p) la_mul_strided((A), (B), (C), (n), (m), (p), 1, (m))
/* X (r x n) = B (r x n) S^-1 for S (n x n, n <= CP_NY): S X' = B' solved by LU with partial pivoting (as LAPACK
 * gesv); S is overwritten. Returns 0, or 1 for a singular S. */
int la_right_solve(cp_real* Sm, const cp_real* B, cp_real* X, int n, int r);

#endif /* CP_LINALG_H */
