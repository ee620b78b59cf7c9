/* select: Hoare's selection (see select.h), once per element type. */
#include "common/select.h"

#define RS_DEFINE_SELECT_KTH(name, T)                              \
    T name(T *v, size_t n, size_t k)                               \
    {                                                              \
        size_t lo = 0, hi = n - 1;                                 \
        while (lo < hi) {                                          \
            T pivot = v[lo + (hi - lo) / 2];                       \
            size_t i = lo, j = hi;                                 \
            while (i <= j) {                                       \
                while (v[i] < pivot) i++;                          \
                while (v[j] > pivot) j--;                          \
                if (i <= j) {                                      \
                    T t = v[i];                                    \
                    v[i] = v[j];                                   \
                    v[j] = t;                                      \
                    i++;                                           \
                    if (j == 0) break;                             \
                    j--;                                           \
                }                                                  \
            }                                                      \
            if (k <= j)                                            \
                hi = j;                                            \
            else if (k >= i)                                       \
                lo = i;                                            \
            else                                                   \
                break; /* v[j + 1 .. i - 1] all equal the pivot */ \
        }                                                          \
        return v[k];                                               \
    }

RS_DEFINE_SELECT_KTH(rs_select_kth, float)
RS_DEFINE_SELECT_KTH(rs_select_kth_double, double)
