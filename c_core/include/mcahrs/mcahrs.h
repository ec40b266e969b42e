/**
 * @file mcahrs.h
 * @brief Everything public, for the bindings and for a flight controller that wants it all.
 */
#ifndef MCAHRS_H
#define MCAHRS_H

#include "mca_config.h"
#include "mca_math.h"
#include "mca_robust.h"
#include "mca_cs.h"
#include "mca_geo.h"
#include "mca_att.h"
#include "mca_nav.h"
#include "mca_profile.h"
#include "mca_replay.h"
#include "mca_ins.h"

#endif /* MCAHRS_H */
