/*
 * sim_real.h: the one real type the whole core is written over, and the pair-time formula.
 *
 * The default build uses IEEE double. The accuracy study builds the same sources with
 *   -DSIM_REAL_F32    float
 *   -DSIM_REAL_F128   __float128 (libquadmath)
 * and, independently of the type, the pair contact time can be computed by
 *   (default)          SPEC's form: cross-product discriminant, root c / (-b + sqrt(disc))
 *   -DSIM_PAIR_REPORT  the seed report's cross-product discriminant with the (-b - sqrt(disc)) / a root
 *   -DSIM_PAIR_TEXTBOOK  disc = b*b - a*c with the (-b - sqrt(disc)) / a root
 * Only the default (double, SPEC form) is the contract; the others exist to be measured.
 */
#ifndef SIM_REAL_H
#define SIM_REAL_H

#include <math.h>

#if defined(SIM_REAL_F32) + defined(SIM_REAL_F128) > 1
#error "choose at most one of SIM_REAL_F32 and SIM_REAL_F128"
#endif
#if defined(SIM_PAIR_REPORT) && defined(SIM_PAIR_TEXTBOOK)
#error "choose at most one of SIM_PAIR_REPORT and SIM_PAIR_TEXTBOOK"
#endif

#if defined(SIM_REAL_F32)
typedef float sim_real;
#define SIM_SQRT sqrtf
#define SIM_REAL_INF HUGE_VALF
#define SIM_REAL_NAME "f32"
#elif defined(SIM_REAL_F128)
#include <quadmath.h>
__extension__ typedef __float128 sim_real;
#define SIM_SQRT sqrtq
#define SIM_REAL_INF ((sim_real)HUGE_VAL)
#define SIM_REAL_NAME "f128"
#else
typedef double sim_real;
#define SIM_SQRT sqrt
#define SIM_REAL_INF HUGE_VAL
#define SIM_REAL_NAME "f64"
#endif

#if defined(SIM_PAIR_REPORT)
#define SIM_FORMULA_NAME "report"
#elif defined(SIM_PAIR_TEXTBOOK)
#define SIM_FORMULA_NAME "textbook"
#else
#define SIM_FORMULA_NAME "spec"
#endif

#endif /* SIM_REAL_H */
