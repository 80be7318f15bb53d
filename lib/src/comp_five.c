/* abbe: the compensator with a five-axis model (abbe/comp.h): model swap and
 * load. The cycles are comp_five_f32.c / comp_five_q.c; the safety layer is
 * comp.c's, unchanged. */
#include "comp_core.h"

#if !defined(ABBE_NO_REVERSAL)
abbe_status_t abbe_comp_swap_five_model(abbe_comp_t *comp, const abbe_five_model_t *model)
{
    /* the linear member is the first: the compensator holds the whole model through it */
    return abbe_comp_swap_model(comp, model != NULL ? &model->linear : NULL);
}

abbe_status_t abbe_comp_load_five_model(abbe_comp_t *comp, abbe_five_model_t *slot, const void *blob, size_t size)
{
    if (comp == NULL || slot == NULL || &slot->linear == comp->model || &slot->linear == comp->pending) {
        return ABBE_E_ARG;
    }
    abbe_status_t st = abbe_five_model_load(slot, blob, size); /* leaves *slot untouched on failure */
    if (st == ABBE_OK) {
        comp->pending = &slot->linear;
    }
    return st;
}
#endif

/* The five-axis model the compensator runs, or NULL for a plain 3-axis one. */
const abbe_five_model_t *abbe_comp_five_model(const abbe_comp_t *comp)
{
    const abbe_model_t *m = comp->model;
    return m != NULL && m->five_view ? (const abbe_five_model_t *)(const void *)m : NULL;
}
