"""The application layer: one function per command, joining compute, storage, pictures and
reports. dice_sweep.cli turns each command's options into one call here and prints its result.
"""
