/* irradiance_share: under MPI, what rank 0 of the irradiance stage computes alone (in
 * rs_par_root_run) and then sends to every rank: the sky map and the sky's harmonics. Each is
 * a second of one core's work at 10^5 facets, repeated on every rank before (a third of a
 * helper rank's CPU time), and a few MB to send. Without MPI, or with one rank, no-ops. */
#ifndef RS_IRRADIANCE_SHARE_H
#define RS_IRRADIANCE_SHARE_H

#include "common/err.h"
#include "sky/skyenv.h"
#include "sky/skysh.h"
#include "light/sunsource.h"

/* Collective: rank 0's sky map (every array, NULL where rank 0's is NULL) and what its build
 * found, into env and info on every rank; the other ranks' env must hold nothing yet. The
 * sun's count of removed pixels too: rank 0 alone took the sun out of the further panoramas.
 * -1 with err set when out of memory on any rank. */
int rs_irradiance_share_sky_map(rs_skyenv *env, rs_skyenv_info *info, rs_sunsource *sun, rs_err *err);

/* Collective: rank 0's harmonics (plain data) into sh on every rank. */
void rs_irradiance_share_sky_sh(rs_skysh *sh);

#endif
