"""What a front end shows of a study, without any GUI: the engine's study run from a panel's values frame by
frame (:mod:`app.frames.compute`), its frames (:mod:`app.frames.frame`), their summary, figures and exports
(:mod:`app.frames.summary`, :mod:`app.frames.render`, :mod:`app.frames.exports`), the data-length study on demand
(:mod:`app.frames.datalength`) and the bounded cache the results share (:mod:`app.frames.cache`)."""
