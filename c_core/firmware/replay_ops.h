/**
 * @file replay_ops.h
 * @brief Vector-replay format: op codes, entry-point ids, record layouts (c_core/firmware/README.md).
 *
 * This header is the one definition of the numbers: scripts/gen_vectors.py reads the
 * RPL_OP_*, RPL_EP_*, RPL_META_* and RPL_COST_* defines from it, so keep them one per
 * line as `#define NAME 0x....u` (or decimal).
 *
 * All files are little-endian. Each starts with a 16-byte header
 *   u32 magic, u16 version (RPL_VERSION), u16 header bytes (16), u32 records, u32 reserved
 * followed by records
 *   u16 op, u16 payload bytes (a multiple of 4), payload (float32 / int32 / uint32 /
 *   uint64 words, no padding)
 * and ends with an RPL_OP_END record of length 0. A reader skips a record it does not
 * know by its length; the replay program refuses one (it cannot run what it does not know).
 */
#ifndef MCA_REPLAY_OPS_H
#define MCA_REPLAY_OPS_H

#define RPL_VERSION 1u
#define RPL_HEADER_BYTES 16u
#define RPL_PAYLOAD_MAX 512u

/* File magics ("MCAV" input vectors, "MCAO" outputs, "MCAC" costs), as little-endian u32. */
#define RPL_MAGIC_IN 0x5641434Du
#define RPL_MAGIC_OUT 0x4F41434Du
#define RPL_MAGIC_COST 0x4341434Du

/* ---- Op codes: input record -> one output record with the same op code. ---- */
#define RPL_OP_END 0x0000u

/* CS maneuver filter (mca_cs.h). Output of every CS op: i32 status, f32 x[3][5],
 * f32 P diagonal[3][5]; CS3_UPDATE adds f32 T[3] (report t_stat, 0 for a skipped axis). */
/* in: cfg_h, cfg_v (each: the 12 f32 fields in mca_cs_config_t order, u32 adaptive,
 *     u32 robust mode; other fields from mca_cs_config_default_h/_v), f32 pos[3],
 *     f32 vel[3], u32 flags (bit 0: pos given, bit 1: vel given; else NULL is passed) */
#define RPL_OP_CS3_INIT 0x0101u
/* in: f32 dt_s */
#define RPL_OP_CS3_PREDICT 0x0102u
/* in: f32 pos[3], vel[3], r_pos[3], r_vel[3], u32 mask[3] */
#define RPL_OP_CS3_UPDATE 0x0103u

/* Navigation top level (mca_nav.h). Output: i32 status (NAV_OUTPUT: i32 0, then the output). */
/* in: u32 preset (0 default, 1 fixed-wing, 2 multirotor, else a NULL config), u32 comp_mode,
 *     u32 yaw_source, u32 CS robust mode, u32 attitude robust mode (0xFFFFFFFF: the preset's) */
#define RPL_OP_NAV_INIT_PRESET 0x0201u
/* in: u64 t_us, f32 gyro_b_rps[3], f32 accel_b_mps2[3] */
#define RPL_OP_NAV_IMU 0x0202u
/* in: u64 t_us, i32 lat_e7, i32 lon_e7, i32 alt_mm, f32 vel_ned_mps[3], f32 h_acc_m, v_acc_m,
 *     s_acc_mps, u32 flags (MCA_FIX_*), u32 fix_type */
#define RPL_OP_NAV_GPS 0x0203u
/* in: u64 t_us, f32 mag_b[3] */
#define RPL_OP_NAV_MAG 0x0204u
/* in: nothing. out: i32 0, u64 t_us, f32 q_nb[4], euler_rad[3], gyro_bias_rps[3], pos_ned_m[3],
 *     vel_ned_mps[3], acc_ned_mps2[3], att_var[6], cs_var[9], rp_t, gps_t[3],
 *     u32 flags, u32 n_grav_obs, u32 n_grav_skip */
#define RPL_OP_NAV_OUTPUT 0x0205u
/* in: an mca_nav_config_t as its bytes (the struct holds float and uint8_t fields only, so its
 *     layout is the same on the host and the M4F; the record's length must be its sizeof, which
 *     replay_main.c checks at compile time is a multiple of 4 within RPL_PAYLOAD_MAX): any
 *     configuration, a robust profile at any fix rate, a receiver model. out: i32 status. */
#define RPL_OP_NAV_INIT_CONFIG 0x0206u

/* Loosely-coupled INS (mca_ins.h), the reference filter. Output: i32 status (INS_OUTPUT: i32 0,
 * then the output). */
/* in: u32 preset (0 default (ground), 1 fixed-wing, 2 multirotor, else a NULL config),
 *     u32 yaw_source, u32 GNSS robust mode (0xFFFFFFFF: the preset's) */
#define RPL_OP_INS_INIT_PRESET 0x0301u
/* in: u64 t_us, f32 gyro_b_rps[3], f32 accel_b_mps2[3] */
#define RPL_OP_INS_IMU 0x0302u
/* in: as NAV_GPS */
#define RPL_OP_INS_GPS 0x0303u
/* in: u64 t_us, f32 mag_b[3] */
#define RPL_OP_INS_MAG 0x0304u
/* in: nothing. out: i32 0, u64 t_us, f32 q_nb[4], euler_rad[3], pos_ned_m[3], vel_ned_mps[3],
 *     i32 lat_e7, lon_e7, alt_mm, f32 gyro_bias_rps[3], accel_bias_mps2[3], p_diag[15], gps_t,
 *     u32 gps_m, flags, n_gps_upd, n_gps_rej, n_gps_skip */
#define RPL_OP_INS_OUTPUT 0x0305u
/* in: an mca_ins_config_t as its bytes (float and uint8_t fields: the same layout on host and
 *     M4F; the record's length must be its sizeof). out: i32 status. */
#define RPL_OP_INS_INIT_CONFIG 0x0306u

/* Measurement self-test (no core call; output: i32 status 0). in: u32 n.
 * Runs a known loop of exactly 2n + 1 instructions (fw_spin) and records its measured cost. */
#define RPL_OP_CAL_SPIN 0x0F01u

/* ---- Entry points whose cost is measured (cost records carry one of these). ---- */
#define RPL_EP_NONE 0u
#define RPL_EP_CS3_INIT 1u
#define RPL_EP_CS3_PREDICT 2u
#define RPL_EP_CS3_UPDATE 3u
#define RPL_EP_NAV_INIT 4u
#define RPL_EP_NAV_IMU 5u
#define RPL_EP_NAV_GPS 6u
#define RPL_EP_NAV_MAG 7u
#define RPL_EP_NAV_OUTPUT 8u
#define RPL_EP_INS_INIT 9u
#define RPL_EP_INS_IMU 10u
#define RPL_EP_INS_GPS 11u
#define RPL_EP_INS_MAG 12u
#define RPL_EP_INS_OUTPUT 13u
#define RPL_EP_CAL_SPIN 15u

/* ---- Cost file: 16-byte records u16 kind, u16 id, u32 a, u32 b, u32 c. ---- */
/* id = entry point, a = instructions, b = stack bytes (painted high-water), c = record index */
#define RPL_COST_CALL 1u
/* id = RPL_META_*, a = value */
#define RPL_COST_META 2u
/* id = 0, a = n, b = instructions (exact method), c = SysTick ticks read directly */
#define RPL_COST_CAL 3u

#define RPL_META_MEASURED 1u      /* 1: counts are real (QEMU), 0: host, no counter */
#define RPL_META_OVERHEAD 2u      /* instructions subtracted per measurement (calibrated) */
#define RPL_META_STACK_BYTES 3u   /* size of the stack region painted */
#define RPL_META_SIZEOF_CS3 4u    /* sizeof(mca_cs3_t): the CS filter's whole state */
#define RPL_META_INSTR_PER_TICK 5u /* instructions per SysTick tick the method assumes */
#define RPL_META_SIZEOF_NAV 6u    /* sizeof(mca_nav_t): the navigation filter's whole state */
#define RPL_META_SIZEOF_INS 7u    /* sizeof(mca_ins_t): the INS's whole state */

/* Status of an op the replay itself rejects (never a core status, those are >= 0). */
#define RPL_STATUS_FORMAT (-1)

#endif /* MCA_REPLAY_OPS_H */
