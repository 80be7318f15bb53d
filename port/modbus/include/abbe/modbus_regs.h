/* abbe Modbus port: the register map (docs/modbus-registers.md).
 *
 * Every register is a holding register (FC03 read, FC06/FC16 write, FC23
 * write-then-read); FC04 reads the same map. A 32-bit value occupies two
 * registers at an even address, in the configured word order
 * (ABBE_MB_REG_CT_WORD_ORDER; ABBE_MB_REG_ID_SELFTEST reads 0x12345678).
 * Writes must cover whole 32-bit values. host_tools/abbe/modbus_client.py
 * mirrors these numbers (a test compares them).
 *
 * This header has no dependencies: a drive with its own Modbus stack can use it.
 */
#ifndef ABBE_MODBUS_REGS_H
#define ABBE_MODBUS_REGS_H

#define ABBE_MB_REGMAP_VERSION 1

/* ---- identity (read only) ------------------------------------------------ */
#define ABBE_MB_REG_ID_BASE 0x0000u
#define ABBE_MB_REG_ID_MAGIC 0x0000u         /* 2 regs: 0x4142 0x4245 ("ABBE") */
#define ABBE_MB_REG_ID_REGMAP 0x0002u        /* ABBE_MB_REGMAP_VERSION */
#define ABBE_MB_REG_ID_LIB_MAJOR 0x0003u     /* ABBE_VERSION_MAJOR, _MINOR, _PATCH */
#define ABBE_MB_REG_ID_LIB_MINOR 0x0004u
#define ABBE_MB_REG_ID_LIB_PATCH 0x0005u
#define ABBE_MB_REG_ID_FMT_MAJOR 0x0006u     /* table format the server reads */
#define ABBE_MB_REG_ID_FMT_MINOR 0x0007u
#define ABBE_MB_REG_ID_SELFTEST 0x0008u      /* u32 0x12345678 in the configured word order */
#define ABBE_MB_REG_ID_MODEL_CRC 0x000Au     /* u32 CRC-32 of the running table, 0 if none */
#define ABBE_MB_REG_ID_MODEL_SIZE 0x000Cu    /* u32 bytes of the running table, 0 if none */
#define ABBE_MB_REG_ID_PENDING_CRC 0x000Eu   /* u32 CRC of the table queued for the next cycle, 0 if none */
#define ABBE_MB_REG_ID_STAGING_MAX 0x0010u   /* u32 staging area size, bytes */
#define ABBE_MB_REG_ID_MODEL_FEATURES 0x0012u /* ABBE_FEATURE_* of the running table */
#define ABBE_MB_REG_ID_MAX_CLIENTS 0x0013u   /* TCP connections served at once (1 for RTU) */
#define ABBE_MB_ID_COUNT 0x0014u

#define ABBE_MB_MAGIC_HI 0x4142u
#define ABBE_MB_MAGIC_LO 0x4245u
#define ABBE_MB_SELFTEST_VALUE 0x12345678u

/* ---- status and counters (read only) -------------------------------------- */
#define ABBE_MB_REG_ST_BASE 0x0020u
#define ABBE_MB_REG_ST_STATE 0x0020u          /* abbe_comp_state_t of the last cycle: 0 OFF, 1 ON, 2 FAULT */
#define ABBE_MB_REG_ST_FLAGS 0x0021u          /* ABBE_FLAG_* of the last cycle */
#define ABBE_MB_REG_ST_CLIENTS 0x0022u        /* TCP connections open now */
#define ABBE_MB_REG_ST_UPLOAD_STATE 0x0023u   /* ABBE_MB_UPLOAD_IDLE / _OPEN */
#define ABBE_MB_REG_ST_CYCLES 0x0024u         /* u32 compensator cycles run */
#define ABBE_MB_REG_ST_REQUESTS 0x0026u       /* u32 requests answered normally */
#define ABBE_MB_REG_ST_EXCEPTIONS 0x0028u     /* u32 requests answered with an exception */
#define ABBE_MB_REG_ST_UPLOADS_OK 0x002Au     /* u32 uploads validated and queued */
#define ABBE_MB_REG_ST_UPLOADS_REJECTED 0x002Cu /* u32 uploads refused or lost (see UP_RESULT) */
#define ABBE_MB_REG_ST_INVALID_INPUTS 0x002Eu /* u32 cycles without fresh positions */
#define ABBE_MB_REG_ST_STALE_EVENTS 0x0030u   /* u32 transitions into stale */
#define ABBE_MB_REG_ST_LIMIT_TRIPS 0x0032u    /* u32 error-limit faults */
#define ABBE_MB_REG_ST_RATE_LIMITED 0x0034u   /* u32 cycles with a rate-limited output */
#define ABBE_MB_REG_ST_MODEL_SWAPS 0x0036u    /* u32 models taken into use */
#define ABBE_MB_REG_ST_CLIENTS_REFUSED 0x0038u /* u32 TCP connections refused (limit reached) */
#define ABBE_MB_REG_ST_LAST_EXCEPTION 0x003Au /* function << 8 | exception code of the last exception */
#define ABBE_MB_ST_COUNT 0x001Bu

/* ---- table upload ---------------------------------------------------------- */
#define ABBE_MB_REG_UP_BASE 0x0050u
#define ABBE_MB_REG_UP_CMD 0x0050u            /* W: ABBE_MB_UP_CMD_BEGIN / _ABORT (FC06 or a 1-register FC16); R: 0 */
#define ABBE_MB_REG_UP_STATE 0x0051u          /* ABBE_MB_UPLOAD_IDLE / _OPEN */
#define ABBE_MB_REG_UP_SESSION 0x0052u        /* id of the open (or last) upload session, 1..65535 */
#define ABBE_MB_REG_UP_RESULT 0x0053u         /* int16 ABBE_MB_UP_* or abbe_status_t of the last upload */
#define ABBE_MB_REG_UP_FILLED 0x0054u         /* u32 bytes received contiguously from offset 0 */
#define ABBE_MB_REG_UP_COMMIT 0x0056u         /* W (exactly these 4 regs, one request): u32 length, u32 CRC-32 */
#define ABBE_MB_REG_UP_COMMIT_LEN 0x0056u
#define ABBE_MB_REG_UP_COMMIT_CRC 0x0058u
#define ABBE_MB_REG_UP_RX_CRC 0x005Au         /* u32 CRC-32 the server computed over the committed bytes */
#define ABBE_MB_REG_UP_MODEL_CRC 0x005Cu      /* u32 table CRC of the last upload that validated */
#define ABBE_MB_UP_COUNT 0x000Eu

#define ABBE_MB_UP_CMD_BEGIN 1u
#define ABBE_MB_UP_CMD_ABORT 2u
#define ABBE_MB_UPLOAD_IDLE 0u
#define ABBE_MB_UPLOAD_OPEN 1u

/* UP_RESULT: 1 OK, 0 nothing yet, a negative abbe_status_t (-1 .. -99, the
 * library's range; today down to ABBE_STATUS_MIN = -19) when the table failed
 * validation, or one of these. */
#define ABBE_MB_UP_OK 1
#define ABBE_MB_UP_NONE 0
#define ABBE_MB_UP_INCOMPLETE (-100)   /* commit length > bytes received */
#define ABBE_MB_UP_CRC_MISMATCH (-101) /* CRC-32 of the received bytes != commit CRC */
#define ABBE_MB_UP_LENGTH (-102)       /* commit length 0 or above the staging size */
#define ABBE_MB_UP_ABORTED (-103)      /* the host aborted (or began again) */
#define ABBE_MB_UP_DISCONNECTED (-104) /* the owner's connection closed mid-upload */
#define ABBE_MB_UP_TIMEOUT (-105)      /* no upload request from the owner for the upload timeout */

/* ---- inputs, written by the controller every cycle -------------------------- */
#define ABBE_MB_REG_IN_BASE 0x0100u
#define ABBE_MB_REG_IN_POS_X 0x0100u          /* int32 nm, machine coordinates */
#define ABBE_MB_REG_IN_POS_Y 0x0102u
#define ABBE_MB_REG_IN_POS_Z 0x0104u
#define ABBE_MB_REG_IN_DIR_X 0x0106u          /* int16 -1, 0, +1 (backlash tables; ignored with CT_DIR_SOURCE = 1) */
#define ABBE_MB_REG_IN_DIR_Y 0x0107u
#define ABBE_MB_REG_IN_DIR_Z 0x0108u
#define ABBE_MB_REG_IN_TEMP_X 0x0109u         /* int16 axis temperature, 0.01 degC (thermal tables), below */
#define ABBE_MB_REG_IN_TEMP_Y 0x010Au
#define ABBE_MB_REG_IN_TEMP_Z 0x010Bu
#define ABBE_MB_REG_IN_AXIS_FAULT 0x010Cu     /* bit j: axis j faulted, its correction fades out */
#define ABBE_MB_REG_IN_CYCLE 0x010Du          /* any write here runs one compensator cycle (the trigger) */
#define ABBE_MB_IN_COUNT 0x000Eu

/* IN_TEMP_*: -5000 .. 15000 (-50 .. +150 degC), or ABBE_MB_TEMP_NO_READING
 * (-32768, 0x8000): no reading, the axis keeps its temperature. Anything else
 * is exception 03 (a sensor fault, not a machine temperature). */
#define ABBE_MB_TEMP_NO_READING (-32768)
#define ABBE_MB_TEMP_MIN_CDEGC (-5000)
#define ABBE_MB_TEMP_MAX_CDEGC 15000

/* ---- outputs of the last cycle (read only) --------------------------------- */
#define ABBE_MB_REG_OUT_BASE 0x0120u
#define ABBE_MB_REG_OUT_CORR_X 0x0120u        /* int32 nm: add to the commanded axis position */
#define ABBE_MB_REG_OUT_CORR_Y 0x0122u
#define ABBE_MB_REG_OUT_CORR_Z 0x0124u
#define ABBE_MB_REG_OUT_ERR_X 0x0126u         /* int32 nm: spatial error dX, dY, dZ at the last valid positions */
#define ABBE_MB_REG_OUT_ERR_Y 0x0128u
#define ABBE_MB_REG_OUT_ERR_Z 0x012Au
#define ABBE_MB_REG_OUT_FLAGS 0x012Cu         /* ABBE_FLAG_* */
#define ABBE_MB_REG_OUT_STATE 0x012Du         /* 0 OFF, 1 ON, 2 FAULT */
#define ABBE_MB_REG_OUT_CYCLE 0x012Eu         /* IN_CYCLE value of the cycle that produced these outputs */
#define ABBE_MB_OUT_COUNT 0x000Fu

/* ---- thermal inputs (read/write; tables of format 1.3 with a thermal block) ----
 * IN_TH_k: input k of the table's thermal model, int16: a temperature in 0.01
 * degC, the spindle speed input in rpm; ABBE_MB_TEMP_NO_READING (-32768) = no
 * reading (the runtime's open-circuit fault). Every other value is taken: the
 * runtime judges it (range, step). Writing IN_TH_SAMPLE hands one sample (the
 * IN_TH registers as they are after the request) to the runtime, IN_TH_DT_MS
 * after the previous one (docs/modbus-registers.md, "Thermal inputs"). */
#define ABBE_MB_REG_TIN_BASE 0x0140u
#define ABBE_MB_REG_IN_TH_0 0x0140u           /* 17 x int16: inputs 0 .. 16 */
#define ABBE_MB_REG_IN_TH_RESERVED 0x0151u    /* 0 */
#define ABBE_MB_REG_IN_TH_DT_MS 0x0152u       /* u32 ms since the previous sample, 1 .. 2^31 (default 1000) */
#define ABBE_MB_REG_IN_TH_SAMPLE 0x0154u      /* any write here hands one sample to the runtime; echoed */
#define ABBE_MB_TIN_COUNT 0x0015u
#define ABBE_MB_TH_INPUTS 17u

/* ---- thermal state (read only) ------------------------------------------------ */
#define ABBE_MB_REG_TOUT_BASE 0x0160u
#define ABBE_MB_REG_TH_FLAGS 0x0160u          /* ABBE_THERMAL_F_* now (abbe/thermal.h) */
#define ABBE_MB_REG_TH_SHAPE 0x0161u          /* inputs << 8 | channels of the running table's block (0: none) */
#define ABBE_MB_REG_TH_INPUT_FAULTS 0x0162u   /* u32 bit k: input k faulted at the last sample */
#define ABBE_MB_REG_TH_EVENTS 0x0164u         /* u32 ABBE_THERMAL_F_* since the start (sticky) */
#define ABBE_MB_REG_TH_CHANNEL_0 0x0166u      /* 5 x int32: channel values, nm (nrad for tilts), unfaded */
#define ABBE_MB_REG_TH_SAMPLES 0x0170u        /* samples handed to the runtime, modulo 65536 */
#define ABBE_MB_REG_TH_SAMPLE_ECHO 0x0171u    /* the IN_TH_SAMPLE value of the last sample */
#define ABBE_MB_TOUT_COUNT 0x0012u

/* ---- control ------------------------------------------------------------------ */
#define ABBE_MB_REG_CT_BASE 0x0200u
#define ABBE_MB_REG_CT_ENABLE 0x0200u         /* 1 enable (fade in), 0 disable (fade out) */
#define ABBE_MB_REG_CT_RESET 0x0201u          /* W 1: clear a latched limit fault (and disable); R: 0 */
#define ABBE_MB_REG_CT_WORD_ORDER 0x0202u     /* ABBE_MB_WORD_ORDER_HIGH_FIRST / _LOW_FIRST */
#define ABBE_MB_REG_CT_DIR_SOURCE 0x0203u     /* 0 IN_DIR registers, 1 sign of the position change */
#define ABBE_MB_REG_CT_FADE_CYCLES 0x0204u    /* limits from here on: writable only while OFF with zero output */
#define ABBE_MB_REG_CT_STALE_CYCLES 0x0205u
#define ABBE_MB_REG_CT_WARN_X 0x0206u         /* int32 nm, > 0 */
#define ABBE_MB_REG_CT_WARN_Y 0x0208u
#define ABBE_MB_REG_CT_WARN_Z 0x020Au
#define ABBE_MB_REG_CT_LIMIT_X 0x020Cu        /* int32 nm, >= warn */
#define ABBE_MB_REG_CT_LIMIT_Y 0x020Eu
#define ABBE_MB_REG_CT_LIMIT_Z 0x0210u
#define ABBE_MB_REG_CT_RATE_X 0x0212u         /* int32 nm per cycle, > 0 */
#define ABBE_MB_REG_CT_RATE_Y 0x0214u
#define ABBE_MB_REG_CT_RATE_Z 0x0216u
#define ABBE_MB_REG_CT_SIGN_X 0x0218u         /* int16 +1 or -1 */
#define ABBE_MB_REG_CT_SIGN_Y 0x0219u
#define ABBE_MB_REG_CT_SIGN_Z 0x021Au
#define ABBE_MB_CT_COUNT 0x001Bu
#define ABBE_MB_CT_FIRST_LIMIT ABBE_MB_REG_CT_FADE_CYCLES

#define ABBE_MB_WORD_ORDER_HIGH_FIRST 0u  /* high word at the lower address (Modbus custom, "ABCD") */
#define ABBE_MB_WORD_ORDER_LOW_FIRST 1u   /* low word first ("CDAB") */

/* ---- staging area for a table upload ---------------------------------------- */
/* Register k holds bytes 2k (high byte) and 2k+1 (low byte) of the blob, so the
 * data bytes of a FC16 request are the blob bytes in order. */
#define ABBE_MB_REG_STAGING 0x1000u

/* Modbus exception codes the port answers with. */
#define ABBE_MB_EX_ILLEGAL_FUNCTION 0x01  /* function not supported, or not allowed in the current state */
#define ABBE_MB_EX_ILLEGAL_ADDRESS 0x02   /* unmapped, read-only, or a partial 32-bit value */
#define ABBE_MB_EX_ILLEGAL_VALUE 0x03     /* count or value out of range; a refused commit */
#define ABBE_MB_EX_DEVICE_FAILURE 0x04
#define ABBE_MB_EX_BUSY 0x06              /* the staging area belongs to another client */

#endif /* ABBE_MODBUS_REGS_H */
