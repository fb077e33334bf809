"""Synthetic drive logs (SPEC §6): the project's own simulator (:mod:`.make_logs`), a second,
deliberately different implementation of the same rover (:mod:`.foreign_logs`, with its soil
in :mod:`.foreign_soil`), and the drive plans both drive (:mod:`.drives`), which calibration's
proposed drives share. Kept apart from calibration: they make the logs it reads."""
