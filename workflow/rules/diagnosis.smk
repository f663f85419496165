# rules for the diagnosis stage (see README)
