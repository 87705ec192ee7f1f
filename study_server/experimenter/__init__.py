"""What the experimenter decides, watches and takes away: decisions and plots while a study runs, exports and
their schema, backups and their restore, and the files of a deployment."""
