$common
    .sp = {
        .table = &fw_task_samples[0][0],
        .n_samples = FW_TASK_SAMPLES,
    },
