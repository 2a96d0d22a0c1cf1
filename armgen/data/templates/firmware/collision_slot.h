static const ctrl_real fw_task_$kind[$size] = $values;
