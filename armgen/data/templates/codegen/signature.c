$returns ${p}_$function($parameters)
