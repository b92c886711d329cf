"""``make bench``: performance measured as ratios against reference runs in the same process."""
