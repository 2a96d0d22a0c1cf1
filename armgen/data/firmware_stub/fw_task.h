/* The task the runners execute, defined by the generated task_params.h (through fw_task.c):
 * the controller's configuration and the runners' drive model (a lock reported from
 * fw_lock_tick on, -1: never, for the joints of fw_lock_mask, bit i: joint i). */
#ifndef ARMGEN_FW_TASK_H
#define ARMGEN_FW_TASK_H

#include <stdint.h>

#include "controller.h"

extern const ctrl_config fw_task;
extern const uint32_t fw_lock_mask;
extern const int32_t fw_lock_tick;

#endif /* ARMGEN_FW_TASK_H */
