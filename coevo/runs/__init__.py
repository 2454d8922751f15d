"""Run tools: a whole run on one machine (:mod:`.local`), offline learning (:mod:`.learn`), fault
injection (:mod:`.chaos`), completeness checks (:mod:`.check`), exact replay (:mod:`.replay`) and the
run directory's layout, its paths and readers (:mod:`.layout`)."""
