/* irradiance_out: what the irradiance stage reports (its metrics, skips and log lines once the
 * gather is done) and writes: irradiance.ply (the mesh with E_sky, G and their uncertainties per
 * facet) and transport.ply (the kernel K, kernel_out.h). */
#ifndef RS_IRRADIANCE_OUT_H
#define RS_IRRADIANCE_OUT_H

#include "common/config.h"
#include "common/err.h"
#include "pipeline/stage.h"
#include "stages/irradiance/irradiance_state.h"

/* The results of a finished run into rep: the gather's (what it left out, its harmonics and
 * rays), the sky map's and the sun's, and the share of E_sky filled in. fill_rate: the fill's
 * uncertainty per square root of radian (rs_skyfill_rate_used). */
void rs_irradiance_report(const rs_irradiance_opts *o, const rs_irradiance_state *s, double fill_rate, rs_report *rep);

/* irradiance.ply and transport.ply into the work folder; the kernel's entry count into rep. */
int rs_irradiance_write(const rs_config *cfg, const rs_irradiance_state *s, double fill_rate, rs_report *rep,
                        rs_err *err);

#endif
