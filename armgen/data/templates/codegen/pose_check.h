/* A pose for ${p}_ik: T (4x4, column-major) with a finite position, last row 0 0 0 1 and a
 * rotation as its 3x3 part (R^T R = I, det R > 0), each entry of T(3, :) - [0 0 0 1] and of
 * R^T R - I within ${P}_POSE_TOL: the default orientation tolerance in double; in float a
 * product of rotations already carries a few 1e-7 of rounding, hence the float IK tolerance.
 * 1 for a pose, 0 otherwise (NaN/inf fail every comparison). */
#if ${P}_USE_FLOAT
#define ${P}_POSE_TOL ${P}_LIT($float_pose_tolerance)
#else
#define ${P}_POSE_TOL ${P}_LIT($pose_tolerance)
#endif
static inline int ${p}_is_pose(const ${p}_real T[16]) {
  const ${p}_real det = ((T[0] * ((T[5] * T[10]) - (T[6] * T[9]))) - (T[4] * ((T[1] * T[10]) - (T[2] * T[9])))) +
                       (T[8] * ((T[1] * T[6]) - (T[2] * T[5])));
  int pose = 1;
  int a;
  int b;
  if (!((det > ${P}_LIT(0.0)) && (${P}_FABS(T[15] - ${P}_LIT(1.0)) <= ${P}_POSE_TOL))) { pose = 0; }
  for (a = 0; a < 3; ++a) {
    if (!((${P}_FABS(T[3 + (4 * a)]) <= ${P}_POSE_TOL) && ((T[12 + a] * ${P}_LIT(0.0)) == ${P}_LIT(0.0)))) { pose = 0; }
    for (b = a; b < 3; ++b) {
      const ${p}_real gram = (T[4 * a] * T[4 * b]) + (T[1 + (4 * a)] * T[1 + (4 * b)]) + (T[2 + (4 * a)] * T[2 + (4 * b)]);
      const ${p}_real unit = (a == b) ? ${P}_LIT(1.0) : ${P}_LIT(0.0);
      if (!(${P}_FABS(gram - unit) <= ${P}_POSE_TOL)) { pose = 0; }
    }
  }
  return pose;
}
