"""The lessons a teacher opens in one click, front-end neutral: their table and texts (:mod:`app.lessons.table`,
the guided start :mod:`app.lessons.start`) and what moves a panel away from one (:mod:`app.lessons.drift`)."""
