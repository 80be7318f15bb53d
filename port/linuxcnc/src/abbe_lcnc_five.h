/* abbe LinuxCNC port, private: the five-axis mode's angles and frames
 * (abbe_lcnc_five.c), used by abbe_lcnc_step() (abbe_lcnc.c). */
#ifndef ABBE_LCNC_FIVE_H
#define ABBE_LCNC_FIVE_H

#include <stdint.h>

#include "abbe_lcnc.h"

/* An angle in degrees reduced to [-180, 180] (the model is periodic in one
 * turn). a must be finite. */
double abbe_lcnc_reduce_deg(double a);

/* The correction v (joint frame, nm) as a world offset w under the
 * tool-centre-point kinematics of table kind ABBE_KIN_* at the joint angles
 * angle_deg (tilt, C; degrees in [-180, 180]). */
void abbe_lcnc_joints_to_workpiece(uint32_t kind, const double angle_deg[ABBE_ROTARY_AXES], const double v[3],
                                   double w[3]);

/* ABBE_LCNC_FRAME_* of the kinematics in force (kinstype: the value of
 * motion.switchkins-type; a 3-axis port is always in the joint frame). */
int32_t abbe_lcnc_frame_of(const abbe_lcnc_t *port, double kinstype);

#endif /* ABBE_LCNC_FIVE_H */
