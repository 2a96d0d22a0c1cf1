/* The task the runners execute: `fw_task` and the lock schedule, defined by the generated
 * task_params.h (armgen firmware-task TASK -o DIR writes it). */
#include "fw_task.h"

#include "task_params.h"
