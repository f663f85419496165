# rules for the report stage (see README)
