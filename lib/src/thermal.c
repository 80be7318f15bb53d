/* abbe: the thermal runtime's shared part (abbe/thermal.h): flags, sizes. */
#include "abbe/thermal.h"

uint32_t abbe_thermal_flags(const abbe_thermal_state_t *st)
{
    return st != NULL ? st->flags : 0u;
}

uint32_t abbe_thermal_events(const abbe_thermal_state_t *st)
{
    return st != NULL ? st->events : 0u;
}

void abbe_thermal_clear_events(abbe_thermal_state_t *st)
{
    if (st != NULL) {
        st->events = 0u;
    }
}

uint32_t abbe_thermal_input_faults(const abbe_thermal_state_t *st)
{
    return st != NULL ? st->input_fault : 0u;
}

size_t abbe_thermal_state_sizeof(void)
{
    return sizeof(abbe_thermal_state_t);
}
