/* abbe CAN port: the node (portable C99, no heap, no I/O).
 *
 * Receive side: every frame is classified; positions and statusword are
 * latched per axis with a "fresh since the previous SYNC" bit. On SYNC one
 * compensator cycle runs on the latched positions (abbe_comp_step_q, fresh =
 * every axis fresh) and the RPDOs / status / info frames are produced.
 */
#include <stddef.h>
#include <string.h>

#include "abbe_can.h"

/* abbe_model_load() reads the coefficients in place and refuses a blob that is
 * not 4-byte aligned (ABBE_E_ALIGN): the slots must be, and are, since the
 * node is aligned for its uint32_t members. */
typedef char abbe_can_blob_align_check[(offsetof(abbe_can_node_t, blob) % 4u == 0u &&
                                        ABBE_CAN_BLOB_MAX % 4u == 0u) ? 1 : -1];

static int running_slot(const abbe_can_node_t *node)
{
    const abbe_model_t *m = abbe_comp_model(&node->comp);
    if (m == &node->model[0]) {
        return 0;
    }
    if (m == &node->model[1]) {
        return 1;
    }
    return -1;
}

/* The slot neither running nor queued, or -1 while a model is queued. */
static int spare_slot(const abbe_can_node_t *node)
{
    if (node->pending_slot >= 0) {
        return -1;
    }
    return running_slot(node) == 0 ? 1 : 0;
}

int abbe_can_node_init(abbe_can_node_t *node, const abbe_can_config_t *cfg)
{
    if (node == NULL || cfg == NULL) {
        return ABBE_CAN_E_ARG;
    }
    abbe_can_config_t c = *cfg;
    if (abbe_can_config_check(&c, NULL, NULL) != ABBE_CAN_OK) {
        return ABBE_CAN_E_CONFIG;
    }
    abbe_comp_config_t cc;
    memset(&cc, 0, sizeof cc);
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        cc.warn_nm[j] = c.axis[j].warn_nm;
        cc.limit_nm[j] = c.axis[j].limit_nm;
        cc.rate_nm_per_cycle[j] = c.axis[j].rate_nm_per_cycle;
        cc.axis_sign[j] = c.axis[j].correction_sign;
    }
    cc.fade_cycles = c.fade_cycles;
    cc.stale_cycles = c.stale_cycles;
    abbe_comp_t comp;
    if (abbe_comp_init(&comp, &cc, NULL) != ABBE_OK) {
        return ABBE_CAN_E_CONFIG;
    }
    memset(node, 0, sizeof *node);
    node->cfg = c;
    node->comp = comp;
    node->pending_slot = -1;
    node->info_countdown = c.info_period_cycles;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        node->temp_mdegc[j] = c.axis[j].temp_mdegc;
        node->temp_age[j] = UINT32_MAX;
    }
    node->temp_frame_age = UINT32_MAX;
    node->temp_stale = c.temp_enable; /* no temperature frame yet */
    node->th_slot = -1;
    if (c.enable_on_start) {
        (void)abbe_comp_enable(&node->comp);
    }
    return ABBE_CAN_OK;
}

const abbe_can_config_t *abbe_can_node_config(const abbe_can_node_t *node)
{
    return node != NULL ? &node->cfg : NULL;
}

/* ---- model slots ----------------------------------------------------------- */

void abbe_can_node_note_load_failure(abbe_can_node_t *node, int status)
{
    if (node == NULL) {
        return;
    }
    node->count.model_loads_failed++;
    node->last_load_status = status;
    node->info_due = 1;
}

uint8_t *abbe_can_node_model_buffer(abbe_can_node_t *node, size_t *capacity)
{
    if (node == NULL) {
        return NULL;
    }
    int s = spare_slot(node);
    if (s < 0) {
        return NULL;
    }
    if (capacity != NULL) {
        *capacity = ABBE_CAN_BLOB_MAX;
    }
    return node->blob[s];
}

int abbe_can_node_commit_model(abbe_can_node_t *node, size_t size)
{
    if (node == NULL) {
        return ABBE_CAN_E_ARG;
    }
    int s = spare_slot(node);
    int st;
    if (s < 0) {
        st = ABBE_CAN_E_BUSY;
    } else if (size > ABBE_CAN_BLOB_MAX) {
        st = ABBE_CAN_E_TOO_BIG;
    } else {
        /* abbe_thermal_load: every check of abbe_model_load, and tables of
         * format 1.3 with their thermal block */
        st = abbe_thermal_load(&node->model[s], &node->thermal[s], node->blob[s], size);
        if (st == ABBE_OK) {
            st = abbe_comp_swap_model(&node->comp, &node->model[s]);
        }
    }
    if (st != ABBE_OK) {
        abbe_can_node_note_load_failure(node, st);
        return st;
    }
    node->pending_slot = (int8_t)s;
    node->count.model_loads_ok++;
    node->last_load_status = ABBE_OK;
    node->info_due = 1;
    return ABBE_CAN_OK;
}

int abbe_can_node_load_model(abbe_can_node_t *node, const void *blob, size_t size)
{
    if (node == NULL || blob == NULL) {
        return ABBE_CAN_E_ARG;
    }
    size_t cap = 0;
    uint8_t *buf = abbe_can_node_model_buffer(node, &cap);
    if (buf == NULL) {
        abbe_can_node_note_load_failure(node, ABBE_CAN_E_BUSY);
        return ABBE_CAN_E_BUSY;
    }
    if (size > cap) {
        abbe_can_node_note_load_failure(node, ABBE_CAN_E_TOO_BIG);
        return ABBE_CAN_E_TOO_BIG;
    }
    memcpy(buf, blob, size);
    return abbe_can_node_commit_model(node, size);
}

int abbe_can_node_model_pending(const abbe_can_node_t *node)
{
    return node != NULL && node->pending_slot >= 0;
}

int abbe_can_node_take_reload_request(abbe_can_node_t *node)
{
    if (node == NULL || !node->reload_requested) {
        return 0;
    }
    node->reload_requested = 0;
    return 1;
}

void abbe_can_node_request_reload(abbe_can_node_t *node)
{
    if (node != NULL) {
        node->reload_requested = 1;
    }
}

int abbe_can_node_enable(abbe_can_node_t *node)
{
    return node != NULL ? (int)abbe_comp_enable(&node->comp) : ABBE_CAN_E_ARG;
}

int abbe_can_node_disable(abbe_can_node_t *node)
{
    return node != NULL ? (int)abbe_comp_disable(&node->comp) : ABBE_CAN_E_ARG;
}

int abbe_can_node_reset(abbe_can_node_t *node)
{
    return node != NULL ? (int)abbe_comp_reset(&node->comp) : ABBE_CAN_E_ARG;
}

/* ---- counters and observers ------------------------------------------------- */

void abbe_can_node_count_malformed(abbe_can_node_t *node)
{
    if (node != NULL) {
        node->count.malformed++;
    }
}

void abbe_can_node_count_tx_error(abbe_can_node_t *node)
{
    if (node != NULL) {
        node->count.tx_errors++;
    }
}

abbe_can_counters_t abbe_can_node_counters(const abbe_can_node_t *node)
{
    abbe_can_counters_t none;
    memset(&none, 0, sizeof none);
    return node != NULL ? node->count : none;
}

uint32_t abbe_can_node_ignored(const abbe_can_node_t *node)
{
    if (node == NULL) {
        return 0;
    }
    const abbe_can_counters_t *c = &node->count;
    return c->bad_dlc + c->unknown_id + c->rtr + c->error_frames + c->bad_command + c->bad_value + c->malformed;
}

const abbe_comp_output_t *abbe_can_node_output(const abbe_can_node_t *node)
{
    return node != NULL ? &node->out : NULL;
}

abbe_comp_stats_t abbe_can_node_comp_stats(const abbe_can_node_t *node)
{
    return abbe_comp_stats(node != NULL ? &node->comp : NULL);
}

uint32_t abbe_can_node_age(const abbe_can_node_t *node, unsigned axis)
{
    return node != NULL && axis < ABBE_AXES ? node->ax[axis].age_cycles : 0u;
}

uint32_t abbe_can_node_model_crc(const abbe_can_node_t *node)
{
    const abbe_model_t *m = node != NULL ? abbe_comp_model(&node->comp) : NULL;
    return m != NULL ? abbe_model_crc(m) : 0u;
}

int32_t abbe_can_node_temp_mdegc(const abbe_can_node_t *node, unsigned axis)
{
    return node != NULL && axis < ABBE_AXES ? node->temp_mdegc[axis] : 0;
}

uint32_t abbe_can_node_temp_age(const abbe_can_node_t *node, unsigned axis)
{
    if (node == NULL || axis > ABBE_AXES) {
        return UINT32_MAX;
    }
    return axis == ABBE_AXES ? node->temp_frame_age : node->temp_age[axis];
}

int abbe_can_node_temp_stale(const abbe_can_node_t *node)
{
    return node != NULL && node->temp_stale;
}

int abbe_can_node_last_load_status(const abbe_can_node_t *node)
{
    return node != NULL ? node->last_load_status : ABBE_CAN_E_ARG;
}

/* ---- the cycle ---------------------------------------------------------------- */

/* Direction with hysteresis: the sign of the last move larger than the
 * deadband, measured from the furthest point reached in the current
 * direction. At standstill it keeps its value (the compensator then sees no
 * distance, so the backlash state does not change). */
static void update_dir(abbe_can_axis_state_t *st, int32_t pos_nm, int32_t deadband_nm)
{
    if (!st->anchor_valid) {
        st->anchor_nm = pos_nm;
        st->anchor_valid = 1;
        return;
    }
    int64_t d = (int64_t)pos_nm - st->anchor_nm;
    if (d > deadband_nm) {
        st->dir = 1;
        st->anchor_nm = pos_nm;
    } else if (d < -(int64_t)deadband_nm) {
        st->dir = -1;
        st->anchor_nm = pos_nm;
    } else if ((d > 0 && st->dir > 0) || (d < 0 && st->dir < 0)) {
        st->anchor_nm = pos_nm;
    }
}

static uint8_t sat_u8(uint32_t v)
{
    return v >= ABBE_CAN_AGE_MAX ? (uint8_t)ABBE_CAN_AGE_MAX : (uint8_t)v;
}

static size_t build_frames(abbe_can_node_t *node, abbe_can_frame_t tx[ABBE_CAN_MAX_TX])
{
    const abbe_can_config_t *cfg = &node->cfg;
    size_t n = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_can_axis_config_t *ax = &cfg->axis[j];
        size_t k = 0;
        while (k < n && tx[k].id != ax->rpdo_cob_id) {
            k++;
        }
        if (k == n) {
            memset(&tx[n], 0, sizeof tx[n]);
            tx[n].id = ax->rpdo_cob_id;
            tx[n].dlc = ax->rpdo_dlc;
            n++;
        }
        abbe_can_put_i32(&tx[k].data[ax->offset_byte], abbe_can_nm_to_incr(ax, node->out.corr_nm[j]));
    }
    uint32_t ignored = abbe_can_node_ignored(node);
    if (cfg->info_period_cycles > 0u) {
        /* every info_period_cycles cycles, plus once after each model load
         * attempt (which does not shift the period) */
        int periodic = 0;
        if (node->info_countdown > 0u) {
            node->info_countdown--;
        }
        if (node->info_countdown == 0u) {
            periodic = 1;
            node->info_countdown = cfg->info_period_cycles;
        }
        if (periodic || node->info_due) {
            abbe_can_frame_t *f = &tx[n++];
            memset(f, 0, sizeof *f);
            f->id = cfg->info_cob_id;
            f->dlc = ABBE_CAN_INFO_DLC;
            abbe_can_put_u32(&f->data[0], abbe_can_node_model_crc(node));
            int ls = node->last_load_status;
            int8_t ls8 = (int8_t)(ls < -128 ? -128 : (ls > 127 ? 127 : ls));
            f->data[4] = (uint8_t)ls8;
            f->data[5] = (uint8_t)(abbe_comp_stats(&node->comp).model_swaps & 0xFFu);
            abbe_can_put_u16(&f->data[6], (uint16_t)(ignored > 0xFFFFu ? 0xFFFFu : ignored));
            node->info_due = 0;
        }
    }
    if (cfg->status_enable) {
        abbe_can_frame_t *f = &tx[n++];
        memset(f, 0, sizeof *f);
        f->id = cfg->status_cob_id;
        f->dlc = ABBE_CAN_STATUS_DLC;
        f->data[0] = (uint8_t)(((unsigned)node->out.state & 0x03u) |
                               (abbe_comp_model(&node->comp) != NULL ? 0x04u : 0u) |
                               (node->last_load_status != 0 ? 0x08u : 0u) |
                               ((unsigned)node->fresh_mask << 4) | (node->temp_stale ? 0x80u : 0u));
        abbe_can_put_u16(&f->data[1], (uint16_t)(node->out.flags & 0xFFFFu));
        f->data[3] = node->seq;
        for (unsigned j = 0; j < ABBE_AXES; j++) {
            f->data[4 + j] = sat_u8(node->ax[j].age_cycles);
        }
        f->data[7] = (uint8_t)(ignored & 0xFFu);
    }
    return n;
}

static uint32_t age_step(uint32_t age, int fresh)
{
    if (fresh) {
        return 0;
    }
    return age < UINT32_MAX - 1u ? age + 1u : UINT32_MAX - 1u; /* UINT32_MAX: never */
}

/* Temperature ages at a SYNC, and TEMP_STALE: the frame is enabled and either
 * none was taken yet, or none (or, for an axis that has had readings, no
 * reading of it) for temp_stale_cycles cycles. */
static void temperature_cycle(abbe_can_node_t *node)
{
    const abbe_can_config_t *cfg = &node->cfg;
    if (node->temp_frame_seen) {
        node->temp_frame_age = age_step(node->temp_frame_age, (node->temp_fresh & 0x08u) != 0u);
    }
    int stale = cfg->temp_enable && !node->temp_frame_seen;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (node->temp_reading & (1u << j)) {
            node->temp_age[j] = age_step(node->temp_age[j], (node->temp_fresh & (1u << j)) != 0u);
            stale |= cfg->temp_stale_cycles > 0u && node->temp_age[j] >= cfg->temp_stale_cycles;
        }
    }
    stale |= cfg->temp_enable && cfg->temp_stale_cycles > 0u && node->temp_frame_seen &&
             node->temp_frame_age >= cfg->temp_stale_cycles;
    node->temp_stale = (uint8_t)(stale != 0);
    node->temp_fresh = 0;
}

/* The thermal state for the model that runs this cycle (a new one starts
 * fresh: no channel running, it fades in after its first good sample);
 * NULL without thermal frames or without a thermal block. */
static abbe_thermal_state_t *thermal_for_cycle(abbe_can_node_t *node)
{
    int slot = node->pending_slot >= 0 ? node->pending_slot : running_slot(node);
    if (!node->cfg.thermal_enable || slot < 0 || node->thermal[slot].n_channels == 0u) {
        node->th_slot = -1;
        return NULL;
    }
    if (slot != node->th_slot) {
        (void)abbe_thermal_init_q(&node->th_state, &node->thermal[slot], node->cfg.cycle_us);
        node->th_slot = (int8_t)slot;
        node->th_valid = 0;
        node->th_sampled = 0;
        node->th_cycles = 0;
    }
    return &node->th_state;
}

static size_t run_cycle(abbe_can_node_t *node, abbe_can_frame_t tx[ABBE_CAN_MAX_TX])
{
    const abbe_can_config_t *cfg = &node->cfg;
    abbe_comp_input_q_t in;
    memset(&in, 0, sizeof in);
    uint8_t fresh_mask = 0, fault_mask = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_can_axis_config_t *ax = &cfg->axis[j];
        abbe_can_axis_state_t *st = &node->ax[j];
        int32_t pos_nm = st->have_pos ? abbe_can_incr_to_nm(ax, st->pos_incr) : 0;
        if (st->fresh) {
            st->age_cycles = 0;
            fresh_mask = (uint8_t)(fresh_mask | (1u << j));
            update_dir(st, pos_nm, ax->deadband_nm);
        } else if (st->age_cycles < UINT32_MAX) {
            st->age_cycles++;
        }
        in.pos_nm[j] = pos_nm;
        in.temp_mdegc[j] = node->temp_mdegc[j];
        in.dir[j] = st->dir;
        if (ax->statusword_byte != ABBE_CAN_NO_BYTE && st->have_pos &&
            (st->statusword & ABBE_CAN_STATUSWORD_FAULT) != 0u) {
            fault_mask = (uint8_t)(fault_mask | (1u << j));
        }
        st->fresh = 0;
    }
    in.fresh = fresh_mask == 0x07u ? 1u : 0u;
    in.axis_fault_mask = fault_mask;
    temperature_cycle(node);
    if (!in.fresh) {
        node->count.stale_cycles++;
    }
    abbe_thermal_state_t *th = thermal_for_cycle(node);
    (void)abbe_comp_step_thermal_q(&node->comp, th, &in, &node->out); /* cannot fail: pointers valid */
    if (th != NULL) {
        node->th_cycles = node->th_cycles < UINT32_MAX ? node->th_cycles + 1u : UINT32_MAX;
        /* a sensor fault, a missing sample or a held channel: the temperatures
         * are not current (the status frame's TempStale bit) */
        if (abbe_thermal_flags(th) & (ABBE_THERMAL_F_FAULTS | ABBE_THERMAL_F_HOLD)) {
            node->temp_stale = 1;
        }
    }
    node->pending_slot = -1; /* a queued model took effect at the start of that step */
    node->fresh_mask = fresh_mask;
    size_t n = build_frames(node, tx);
    node->seq++;
    node->count.syncs++;
    node->count.frames_tx += (uint32_t)n;
    return n;
}

static int rx_command(abbe_can_node_t *node, const abbe_can_frame_t *rx)
{
    if (rx->dlc != 1u) {
        node->count.bad_dlc++;
        return ABBE_CAN_RX_BAD_DLC;
    }
    switch (rx->data[0]) {
    case ABBE_CAN_CMD_ENABLE: (void)abbe_comp_enable(&node->comp); break;
    case ABBE_CAN_CMD_DISABLE: (void)abbe_comp_disable(&node->comp); break;
    case ABBE_CAN_CMD_RESET: (void)abbe_comp_reset(&node->comp); break;
    case ABBE_CAN_CMD_RELOAD: node->reload_requested = 1; break;
    default: node->count.bad_command++; return ABBE_CAN_RX_BAD_COMMAND;
    }
    node->count.commands++;
    return ABBE_CAN_RX_COMMAND;
}

/* The whole frame is checked before any value is taken. */
static int rx_temperature(abbe_can_node_t *node, const abbe_can_frame_t *rx)
{
    if (rx->dlc != ABBE_CAN_TEMP_DLC) {
        node->count.bad_dlc++;
        return ABBE_CAN_RX_BAD_DLC;
    }
    int32_t cdegc[ABBE_AXES];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        uint16_t u = abbe_can_get_u16(&rx->data[2u * j]);
        cdegc[j] = u <= 0x7FFFu ? (int32_t)u : (int32_t)u - 65536;
        if (cdegc[j] != ABBE_CAN_TEMP_NO_READING &&
            (cdegc[j] < ABBE_CAN_TEMP_MIN_CDEGC || cdegc[j] > ABBE_CAN_TEMP_MAX_CDEGC)) {
            node->count.bad_value++;
            return ABBE_CAN_RX_BAD_VALUE;
        }
    }
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        if (cdegc[j] != ABBE_CAN_TEMP_NO_READING) {
            node->temp_mdegc[j] = 10 * cdegc[j];
            node->temp_reading = (uint8_t)(node->temp_reading | (1u << j));
            node->temp_fresh = (uint8_t)(node->temp_fresh | (1u << j));
            if (node->temp_age[j] == UINT32_MAX) {
                node->temp_age[j] = 0;
            }
        }
    }
    node->temp_fresh = (uint8_t)(node->temp_fresh | 0x08u);
    if (!node->temp_frame_seen) {
        node->temp_frame_seen = 1;
        node->temp_frame_age = 0;
    }
    node->count.temperatures++;
    return ABBE_CAN_RX_TEMPERATURE;
}

/* A thermal frame: its four readings into the sample; the frame with the
 * model's last input hands the sample to the runtime (inputs without a
 * reading in it are invalid: the runtime holds and fades what reads them). */
static int rx_thermal(abbe_can_node_t *node, const abbe_can_frame_t *rx, unsigned group)
{
    if (rx->dlc != ABBE_CAN_THERMAL_DLC) {
        node->count.bad_dlc++;
        return ABBE_CAN_RX_BAD_DLC;
    }
    node->count.thermal_frames++;
    if (thermal_for_cycle(node) == NULL) {
        return ABBE_CAN_RX_THERMAL; /* no thermal block (or a model queued without one): taken, not used */
    }
    const abbe_thermal_model_t *tm = &node->thermal[node->th_slot];
    for (unsigned i = 0; i < ABBE_CAN_THERMAL_PER_FRAME; i++) {
        unsigned k = group * ABBE_CAN_THERMAL_PER_FRAME + i;
        if (k >= tm->n_inputs) {
            break;
        }
        uint16_t u = abbe_can_get_u16(&rx->data[2u * i]);
        int32_t v = u <= 0x7FFFu ? (int32_t)u : (int32_t)u - 65536;
        if (v == ABBE_CAN_TEMP_NO_READING) {
            node->th_valid &= ~(1u << k);
            continue;
        }
        node->th_x[k] = tm->kind[k] == ABBE_THERMAL_SPEED ? v : 10 * v; /* rpm; 0.01 degC -> m degC */
        node->th_valid |= 1u << k;
    }
    if ((tm->n_inputs - 1u) / ABBE_CAN_THERMAL_PER_FRAME == group) {
        uint64_t dt_ms = (uint64_t)node->th_cycles * node->cfg.cycle_us / 1000u;
        dt_ms = dt_ms < 1u ? 1u : (dt_ms > 0x7FFFFFFFu ? 0x7FFFFFFFu : dt_ms);
        (void)abbe_thermal_update_q(&node->th_state, node->th_x, node->th_valid, (uint32_t)dt_ms);
        node->th_valid = 0;
        node->th_cycles = 0;
        node->th_sampled = 1;
        node->count.thermal_samples++;
    }
    return ABBE_CAN_RX_THERMAL;
}

static int rx_position(abbe_can_node_t *node, const abbe_can_frame_t *rx)
{
    int matched = 0;
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        const abbe_can_axis_config_t *ax = &node->cfg.axis[j];
        if (ax->tpdo_cob_id != rx->id) {
            continue;
        }
        if (rx->dlc != ax->tpdo_dlc) { /* axes sharing a TPDO share its DLC */
            node->count.bad_dlc++;
            return ABBE_CAN_RX_BAD_DLC;
        }
        abbe_can_axis_state_t *st = &node->ax[j];
        st->pos_incr = abbe_can_get_i32(&rx->data[ax->position_byte]);
        if (ax->statusword_byte != ABBE_CAN_NO_BYTE) {
            st->statusword = abbe_can_get_u16(&rx->data[ax->statusword_byte]);
        }
        st->have_pos = 1;
        st->fresh = 1;
        matched = 1;
    }
    if (!matched) {
        node->count.unknown_id++;
        return ABBE_CAN_RX_UNKNOWN;
    }
    node->count.positions++;
    return ABBE_CAN_RX_POSITION;
}

int abbe_can_node_rx(abbe_can_node_t *node, const abbe_can_frame_t *rx,
                     abbe_can_frame_t tx[ABBE_CAN_MAX_TX], size_t *n_tx)
{
    if (node == NULL || rx == NULL || tx == NULL || n_tx == NULL) {
        return ABBE_CAN_E_ARG;
    }
    *n_tx = 0;
    node->count.frames_rx++;
    const abbe_can_config_t *cfg = &node->cfg;
    if (rx->id & ABBE_CAN_ERR_FLAG) {
        node->count.error_frames++;
        return ABBE_CAN_RX_ERROR;
    }
    if (rx->id & ABBE_CAN_RTR_FLAG) {
        node->count.rtr++;
        return ABBE_CAN_RX_RTR;
    }
    if ((rx->id & ABBE_CAN_EFF_FLAG) || rx->id > ABBE_CAN_SFF_MASK) {
        node->count.unknown_id++;
        return ABBE_CAN_RX_UNKNOWN;
    }
    if (rx->id == cfg->sync_cob_id) {
        if (rx->dlc > 1u) { /* CiA 301: no data, or the 1-byte SYNC counter */
            node->count.bad_dlc++;
            return ABBE_CAN_RX_BAD_DLC;
        }
        *n_tx = run_cycle(node, tx);
        return ABBE_CAN_RX_SYNC;
    }
    if (cfg->command_enable && rx->id == cfg->command_cob_id) {
        return rx_command(node, rx);
    }
    if (cfg->temp_enable && rx->id == cfg->temp_cob_id) {
        return rx_temperature(node, rx);
    }
    if (cfg->thermal_enable && rx->id >= cfg->thermal_cob_id &&
        rx->id < cfg->thermal_cob_id + ABBE_CAN_THERMAL_FRAMES) {
        return rx_thermal(node, rx, rx->id - cfg->thermal_cob_id);
    }
    return rx_position(node, rx);
}

const abbe_thermal_state_t *abbe_can_node_thermal(const abbe_can_node_t *node)
{
    return node != NULL && node->th_slot >= 0 ? &node->th_state : NULL;
}
