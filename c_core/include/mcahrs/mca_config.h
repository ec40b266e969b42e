/**
 * @file mca_config.h
 * @brief Compile-time sizes of MCAHRS. Every array and every loop bound in the core comes
 *        from here, so the worst-case memory and time are known at build time.
 */
#ifndef MCA_CONFIG_H
#define MCA_CONFIG_H

/** Largest measurement dimension of any update (position + velocity, 3 axes). */
#define MCA_MEAS_MAX 6

/** States of one CS maneuver-filter axis: [p, v, a, eps_p, eps_v]. */
#define MCA_CS_NX 5

/** Largest measurement of one CS axis (position, velocity). */
#define MCA_CS_NZ 2

/** Scratch floats a Kalman update of n states and m measurements needs (mca_kf_update). */
#define MCA_KF_WS_LEN(n, m) ((n) * (n) + 4 * (n) * (m) + 4 * (m) * (m) + (n) + (m))

#endif /* MCA_CONFIG_H */
