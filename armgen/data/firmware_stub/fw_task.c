/* The task the runners execute: `fw_task`, defined by the generated task_params.h
 * (python -m armgen.verify.firmware header TASK -o DIR writes it). */
#include "controller.h"

#include "task_params.h"
