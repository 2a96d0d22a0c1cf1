/* The task's collision check (docs/collision.md, "On the board"): $obstacles in the obstacle
 * slots of the generated collision functions (one column per slot, column-major; the slots
 * after the given obstacles inactive), [collision] clearance $clearance m, activation $activation m,
 * gain $gain$gain_note. */
typedef char fw_task_check_collision[(CTRL_HAS_COLLISION == 1) ? 1 : -1]; /* -DCTRL_HAS_COLLISION=1 */
typedef char fw_task_check_ndist[(CTRL_NDIST == $ndist) ? 1 : -1]; /* the robot's collision model */
$slots
static void fw_task_distances(const ctrl_real *q, ctrl_real *d) {
  ctrl_gen_collision_distances(q, ${arguments}d);
}
$criterion
static const ctrl_collision fw_task_collision = {
  .clearance = $clearance_literal,
  .activation = $activation_literal,
  .gain = $gain_literal,
  .distances = fw_task_distances,
  .criterion = $criterion_name,
};
