static void fw_task_criterion(const ctrl_real *q, ctrl_real clearance, ctrl_real activation, ctrl_real *h,
                              ctrl_real *grad) {
  ctrl_gen_collision_criterion(q, ${arguments}clearance, activation, h, grad);
}
