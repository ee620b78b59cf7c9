/* irradiance_close: the occluders of the irradiance stage ([irradiance] occluders): the free-space
 * map of the scanners' and the camera's rays (meshing/freespace.h), its faces written to
 * occluders.ply, or a given occluder file, attached to the stage's scene (rs_scene_set_occluders)
 * so that every gather, sun and search ray on it sees the closed model. */
#ifndef RS_IRRADIANCE_CLOSE_H
#define RS_IRRADIANCE_CLOSE_H

#include "common/config.h"
#include "common/err.h"
#include "pipeline/stage.h"
#include "stages/irradiance/irradiance_state.h"

/* Builds or reads the occluders as [irradiance] says and attaches them to s->scene (after the
 * sky map: the sky panorama's mask must not see them). With occluders = off it removes an
 * occluders.ply an earlier run left. Figures into rep (metrics "occluders"). */
int rs_irradiance_close(const rs_config *cfg, rs_irradiance_state *s, rs_report *rep, rs_err *err);

#endif
