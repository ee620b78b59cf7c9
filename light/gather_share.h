/* gather_share: a gather split over MPI ranks (common/par.h) made whole again: every rank holds
 * every gathered facet afterwards, byte for byte what a single process would hold. */
#ifndef RS_GATHER_SHARE_H
#define RS_GATHER_SHARE_H

#include <stddef.h>
#include <stdint.h>
#include "light/gather.h"

/* Collective. The facets list[k] with mine[k] set were gathered here into fg[k] (by_position)
 * or fg[list[k]]; the others were gathered by other ranks. Copies every rank's facets (their K
 * rows too, malloc'd) into the same places on every rank. 0, or -1 when out of memory. */
int rs_gather_share(const uint32_t *list, size_t n, rs_facet_gather *fg, int by_position, const uint8_t *mine);

#endif
