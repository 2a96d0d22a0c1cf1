typedef char fw_task_check_nseg[(CTRL_MAX_SEGMENTS >= $nseg) ? 1 : -1];
