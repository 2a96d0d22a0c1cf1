  {"$function", (PyCFunction)(void (*)(void))${p}_api_$function, METH_FASTCALL, "$function(count, $names)"},
