/* abbe: geometric error model and compensation for 3-axis machine tools.
 * One include for the whole public API. */
#ifndef ABBE_ABBE_H
#define ABBE_ABBE_H

#include "abbe/comp.h"
#include "abbe/error.h"
#include "abbe/five_axis.h"
#include "abbe/model.h"
#include "abbe/status.h"
#include "abbe/thermal.h"
#include "abbe/version.h"

#endif /* ABBE_ABBE_H */
