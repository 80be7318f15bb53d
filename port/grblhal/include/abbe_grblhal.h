/* abbe grblHAL plugin: geometric error compensation on grblHAL's kinematics
 * interface (docs/grblhal.md).
 *
 * Build grblHAL with KINEMATICS_API defined, add the sources in port/grblhal/src/ and the
 * abbe library (lib/) to the firmware, and call abbe_grblhal_init() from the
 * driver's init (driver_init(), where plugins are initialised; or from
 * my_plugin_init()). With ABBE_GRBLHAL_BUILTIN defined the table of
 * abbe_model.c / abbe_model.h (`abbe table cgen`) is compiled in; without it
 * the plugin starts without a table until one is uploaded ($ABBEU, see the
 * docs). It must be the only kinematics (a Cartesian machine).
 */
#ifndef ABBE_GRBLHAL_H
#define ABBE_GRBLHAL_H

/* $ settings: enable, segment deviation bound (um), maximum correction (um). */
#ifndef ABBE_GRBLHAL_SETTING_BASE
#define ABBE_GRBLHAL_SETTING_BASE 450 /* Setting_UserDefined_0 */
#endif

void abbe_grblhal_init(void);

#endif /* ABBE_GRBLHAL_H */
