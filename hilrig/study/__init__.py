"""Studies: a folder of recorded sessions as one study, from a catalogue to a report.

The workflow (docs/study.md)::

    hilrig study index DIR          # the catalogue: every session's metadata and quality flags
    hilrig study list DIR --where "controller == 'adaptive'"
    hilrig study exclude DIR SESSION[#EVENT] --reason "..."   # kept in DIR/study.toml
    hilrig report DIR -o report.html                          # statistics and figures
    hilrig study simulate DIR --subjects 8 ...                # a synthetic study, emulated rig
"""
