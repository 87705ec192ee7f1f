# Reproduces the likelihood-ratio tests and fixed effects of this report with R's lme4.
# Written by `scenesuggest analyze report`; reads the report's measures/ folder beside this file.
#
#   Rscript reproduce.R                 (needs R with lme4; Debian: apt-get install r-cran-lme4)
#
# Models (as the report fits them): each measure with and without condition, maximum likelihood, with the random
# effects the report chose for the measure (its table "Random effects chosen"; a slope of condition is a slope on
# the condition's treatment dummies .condition2, .condition3, …, which this script makes), and again with crossed
# random intercepts for participant and scene alone (a factor with a single level is left out); models with slopes
# are fitted from four starts and the best kept, as one optimum can hide another; counts as a Poisson GLMM
# (log link, Laplace) with glmer's inner solve tightened (tolPwrss = 1e-13): with its default 1e-7, glmer's
# standard errors can be off by a percent or so; tightened, they match the report's to ~1e-4 on most data and
# within ~0.5% on all (glmer evaluates the Laplace log-determinant one inner iteration behind; the report uses the
# converged value). Fixed effects are treatment-coded against the first condition.
suppressMessages(library(lme4))

here <- local({  # this script's folder, run by Rscript (which writes a space as "~+~") or source()d
  file <- gsub("~+~", " ", sub("^--file=", "", grep("^--file=", commandArgs(FALSE), value = TRUE)), fixed = TRUE)
  sourced <- tryCatch(sys.frame(1)$ofile, error = function(e) NULL)
  if (!is.null(sourced)) dirname(normalizePath(sourced))
  else if (length(file) == 1) dirname(normalizePath(file)) else getwd()
})
conditions <- c("none", "basic", "full")
measures <- data.frame(
  measure = c("total_time", "rotation_time", "translation_time", "translation_distance", "n_queries", "reciprocal_rank", "score"),
  label = c("Total time (s)", "Rotation time (s)", "Translation time (s)", "Translation distance (m)", "Model queries", "MRR", "Score (0–1)"),
  family = c("gaussian", "gaussian", "gaussian", "gaussian", "poisson", "gaussian", "gaussian"),
  rows = c("trials", "trials", "trials", "trials", "trials", "picks", "trials"),
  random = c("(1 + .condition2 + .condition3 | participant) + (1 + .condition2 + .condition3 | scene)", "(1 | participant) + (0 + .condition2 | participant) + (1 | scene) + (0 + .condition3 | scene)", "(1 | participant) + (0 + .condition2 | participant) + (1 | scene) + (0 + .condition2 | scene) + (0 + .condition3 | scene)", "(1 | participant) + (0 + .condition2 | participant) + (0 + .condition3 | participant) + (1 | scene) + (0 + .condition3 | scene)", "(1 | participant) + (1 | scene)", "(1 | participant) + (1 | scene) + (0 + .condition2 | scene) + (0 + .condition3 | scene)", "(1 | participant) + (0 + .condition3 | participant) + (1 | scene) + (0 + .condition3 | scene)"),
  stringsAsFactors = FALSE)

# Ids are text ("01" is not "1", and a scene called "NA" is a scene); only an empty field is missing.
ids <- c(participant = "character", scene = "character", condition = "character")
trials <- read.csv(file.path(here, "measures", "trials.csv"), colClasses = ids, na.strings = "")
trials <- trials[as.logical(as.character(trials$complete)), ]
picks <- read.csv(file.path(here, "measures", "picks.csv"), colClasses = ids, na.strings = "")
converged <- glmerControl(optimizer = "bobyqa", tolPwrss = 1e-13, optCtrl = list(rhoend = 1e-10, maxfun = 1e5))
lmm_converged <- lmerControl(optimizer = "bobyqa", optCtrl = list(rhoend = 1e-12, maxfun = 1e5))
starts <- c(1, 0.5, 0.2, 2)  # θ = s times the identity; lme4's own start is s = 1

# A measure is not modelled when a test of condition would say nothing true — the report's rule
# (analysis/degenerate.py), in its words: no variance, none within a condition (a ceiling or a floor), a count that
# is zero throughout a condition, a fit that reproduces every value exactly, or one below its nested null.
joined <- function(x) if (length(x) > 1) paste(paste(head(x, -1), collapse = ", "), "and", tail(x, 1)) else x
check_data <- function(d, family) {
  rows <- split(d$y, d$condition)
  if (family == "poisson") {
    if (all(d$y == 0)) stop("is zero everywhere; there is nothing to model")
    zero <- Filter(function(c) all(rows[[c]] == 0), names(rows))
    if (length(zero)) stop(sprintf("is zero in every row of %s: its log rate there has no finite estimate (a floor)",
                                   joined(zero)))
  } else {
    if (length(unique(d$y)) < 2) stop("is constant; there is no variance to model")
    flat <- Filter(function(c) length(rows[[c]]) > 1 && length(unique(rows[[c]])) == 1, names(rows))
    if (length(flat)) {
      values <- paste(sprintf("every value in %s is %g", flat, sapply(flat, function(c) rows[[c]][1])),
                      collapse = "; ")
      stop(sprintf(paste("has no variance within a level of condition (%s): a ceiling or a floor, which a linear",
                         "model with one residual variance cannot describe"), values))
    }
  }
}
check_fit <- function(d, family, f1, f0) {
  if (family != "poisson" && nrow(d) > 1 && sigma(f1)^2 < 1e-06 * var(d$y)) {
    stop(paste("the model reproduces every value exactly (no residual variance): its standard errors are",
               "rounding noise"))
  }
  l1 <- as.numeric(logLik(f1))
  l0 <- as.numeric(logLik(f0))
  if (l1 < l0 - 1e-06) {
    stop(sprintf(paste("the fit failed: the model with condition has a lower log-likelihood (%.6g) than the model",
                       "without it (%.6g)"), l1, l0))
  }
  se <- sqrt(diag(as.matrix(vcov(f1))))
  if (!all(is.finite(c(fixef(f1), se))) || min(se) <= 0) {
    stop("the fit is degenerate: an estimate or standard error is not a finite positive number")
  }
}

fit_measure <- function(m) {
  d <- if (m$rows == "picks") picks else trials
  d <- d[d$condition %in% conditions & !is.na(d[[m$measure]]), ]
  d$y <- d[[m$measure]]
  d$condition <- droplevels(factor(d$condition, levels = conditions))
  groups <- Filter(function(g) length(unique(d[[g]])) > 1, c("participant", "scene"))
  # the report's model matrices refuse these first (analysis/design.py), in these words
  if (length(groups) == 0) stop("a mixed model needs at least one random term")
  if (nrow(d) < 3) stop(sprintf("only %d complete row(s)", nrow(d)))
  if (nlevels(d$condition) < 2) {
    stop(sprintf("'condition' has %d level(s) with data; a fixed effect needs at least 2", nlevels(d$condition)))
  }
  check_data(d, m$family)
  for (k in seq_along(conditions)[-1]) d[[paste0(".condition", k)]] <- as.numeric(d$condition == conditions[k])
  intercepts <- paste(sprintf("(1 | %s)", groups), collapse = " + ")
  random <- if (nzchar(m$random)) m$random else intercepts
  one <- function(formula, start = NULL) if (m$family == "poisson") {
    glmer(formula, d, family = poisson, control = converged, start = start)
  } else if (is.null(start)) {
    lmer(formula, d, REML = FALSE)
  } else {
    lmer(formula, d, REML = FALSE, control = lmm_converged, start = start)
  }
  fit <- function(formula, slopes) suppressMessages(if (slopes) {  # the best of several starts
    lower <- lFormula(formula, d)$reTrms$lower
    fits <- Filter(Negate(is.null), lapply(starts, function(s) tryCatch(
      one(formula, list(theta = ifelse(lower == 0, s, 0))), error = function(e) NULL)))
    if (!length(fits)) stop("no start of the model with random slopes could be fitted")
    fits[[which.max(sapply(fits, function(f) as.numeric(logLik(f))))]]
  } else {
    one(formula)
  })
  test <- function(random) {
    f1 <- fit(as.formula(paste("y ~ condition +", random)), random != intercepts)
    f0 <- fit(as.formula(paste("y ~ 1 +", random)), random != intercepts)
    check_fit(d, m$family, f1, f0)
    a <- anova(f0, f1)
    df <- if ("Chi Df" %in% names(a)) a[["Chi Df"]][2] else a$Df[2]  # lme4 before 1.1-23 named it so
    list(chisq = a$Chisq[2], df = df, n = nobs(f1), p = a[["Pr(>Chisq)"]][2], f1 = f1)
  }
  chosen <- test(random)
  alone <- if (random == intercepts) chosen else test(intercepts)
  f1 <- chosen$f1
  messages <- c(if (isSingular(f1)) "boundary (singular) fit: see help('isSingular')",
                unlist(f1@optinfo$conv$lme4$messages))
  c(chosen[c("chisq", "df", "n", "p")], list(chisq0 = alone$chisq, p0 = alone$p, random = random,
    fixef = fixef(f1), se = sqrt(diag(as.matrix(vcov(f1)))),
    note = gsub("\n", " ", paste(unique(messages), collapse = "; "))))
}

cat(sprintf("Likelihood-ratio tests of condition (%s, lme4 %s)\n", R.version.string, packageVersion("lme4")))
cat(sprintf("%-22s %-8s %14s %3s %6s %14s %14s %14s  %s\n", "measure", "model", "chisq", "df", "N", "p",
            "chisq (int.)", "p (int.)", "note"))
fits <- list()
for (i in seq_len(nrow(measures))) {
  m <- measures[i, ]
  fitted <- tryCatch(fit_measure(m), error = function(e) conditionMessage(e))
  fits[[m$measure]] <- fitted
  model <- if (m$family == "poisson") "GLMM" else "LMM"
  if (is.character(fitted)) {
    cat(sprintf("%-22s %-8s not modelled: %s\n", m$measure, model, fitted))
  } else {
    cat(sprintf("%-22s %-8s %14.8g %3d %6d %14.8g %14.8g %14.8g  %s\n", m$measure, model, fitted$chisq, fitted$df,
                fitted$n, fitted$p, fitted$chisq0, fitted$p0, fitted$note))
  }
}
cat("\nRandom effects of each measure's models (int.: the same test with random intercepts alone)\n")
for (name in names(fits)) if (!is.character(fits[[name]])) cat(sprintf("%-22s %s\n", name, fits[[name]]$random))
cat("\nFixed effects of the full models (estimate, standard error)\n")
cat(sprintf("%-22s %-28s %16s %16s\n", "measure", "term", "estimate", "se"))
for (name in names(fits)) {
  fitted <- fits[[name]]
  if (is.character(fitted)) next
  for (term in names(fitted$fixef)) {
    cat(sprintf("%-22s %-28s %16.10g %16.10g\n", name, term, fitted$fixef[[term]], fitted$se[[term]]))
  }
}
