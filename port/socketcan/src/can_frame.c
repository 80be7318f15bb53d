/* abbe CAN port: little-endian fields and the status / info frame payloads. */
#include "abbe_can.h"

void abbe_can_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

uint16_t abbe_can_get_u16(const uint8_t *p)
{
    return (uint16_t)((unsigned)p[0] | ((unsigned)p[1] << 8));
}

void abbe_can_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)(v >> 24);
}

uint32_t abbe_can_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

void abbe_can_put_i32(uint8_t *p, int32_t v)
{
    abbe_can_put_u32(p, (uint32_t)v); /* two's complement bit pattern */
}

int32_t abbe_can_get_i32(const uint8_t *p)
{
    uint32_t u = abbe_can_get_u32(p);
    /* Convert without implementation-defined behaviour for u >= 2^31. */
    return u <= (uint32_t)INT32_MAX ? (int32_t)u : (int32_t)(u - 0x80000000u) + INT32_MIN;
}

int abbe_can_status_decode(const abbe_can_frame_t *f, abbe_can_status_frame_t *s)
{
    if (f == NULL || s == NULL || f->dlc != ABBE_CAN_STATUS_DLC) {
        return ABBE_CAN_E_ARG;
    }
    s->state = (uint8_t)(f->data[0] & 0x03u);
    s->model_loaded = (uint8_t)((f->data[0] >> 2) & 1u);
    s->load_failed = (uint8_t)((f->data[0] >> 3) & 1u);
    s->fresh_mask = (uint8_t)((f->data[0] >> 4) & 0x07u);
    s->temp_stale = (uint8_t)((f->data[0] >> 7) & 1u);
    s->flags = abbe_can_get_u16(&f->data[1]);
    s->seq = f->data[3];
    for (unsigned j = 0; j < ABBE_AXES; j++) {
        s->age[j] = f->data[4 + j];
    }
    s->ignored = f->data[7];
    return ABBE_CAN_OK;
}

int abbe_can_info_decode(const abbe_can_frame_t *f, abbe_can_info_frame_t *s)
{
    if (f == NULL || s == NULL || f->dlc != ABBE_CAN_INFO_DLC) {
        return ABBE_CAN_E_ARG;
    }
    s->model_crc = abbe_can_get_u32(&f->data[0]);
    s->load_status = (int8_t)(f->data[4] <= 127u ? (int)f->data[4] : (int)f->data[4] - 256);
    s->model_swaps = f->data[5];
    s->ignored = abbe_can_get_u16(&f->data[6]);
    return ABBE_CAN_OK;
}
