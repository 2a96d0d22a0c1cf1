#define FW_TASK_SAMPLES $rows
typedef char fw_task_check_nsamples[(CTRL_MAX_SAMPLES >= FW_TASK_SAMPLES) ? 1 : -1];
/* The plan's joint samples, row k = tick k (robot joint order; m for the prismatic joints, rad
 * for the revolute ones). const: it stays in flash and never changes; fw_task points to it.
 * Each value is the plan's double: exact in double, rounded once in float. */
static const ctrl_real fw_task_samples[FW_TASK_SAMPLES][CTRL_NDOF] = {
$samples
};
